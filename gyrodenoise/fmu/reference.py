"""Reference results carried by every FMU: an input CSV and the output CSV expected from it.

Laid out as the Modelica Reference-FMUs do (each model ships ``<Model>_in.csv`` with its input
signals and ``<Model>_ref.csv`` with the expected result; their FMU archives carry the model's
documentation and reference plot under ``documentation/``): every gyrodenoise FMU, FMI 2.0 and
3.0, native and pythonfmu, carries ``documentation/<Model>_in.csv`` and
``documentation/<Model>_ref.csv``. The expected outputs are produced by the library
(:func:`gyrodenoise.denoise` and :func:`gyrodenoise.simulate`), never by an FMU.

The run: :data:`N_SAMPLES` rows at the FMUs' default sample period h = 0.005 s, every parameter
at its start value, a restart in the input row :data:`RESTART_AT` (the default warm-up is 1 s =
200 samples, so the run shows warm-up, filtering, a restart and filtering again).

The files follow the convention of the Reference-FMUs' host ``fmusim`` (v0.0.39), which fmpy's
``simulate_fmu`` shares: the input row at t = 0 is set in initialisation mode and the outputs
at t = 0 are read after ExitInitializationMode; input row k is set before the step that starts
at t_k = k h, and the outputs after that step are written at its end, t_(k+1). So a model sees
row k during the step [t_k, t_(k+1)]:

* a sensor takes sample 0 at initialisation from row 0 and sample k + 1 in the step
  [t_k, t_(k+1)] from row k: its output row 0 is ``simulate``'s sample 0 of the inputs
  (row 0, row 0, row 1, ..., row N-2) and row j >= 1 that run's sample j (a restart in input
  row k shows in output row k + 1);
* a denoiser filters row k in the step [t_k, t_(k+1)]: output row k + 1 is ``denoise``'s
  sample k of the input rows; output row 0, read before the first step, is the first output for
  row 0 (the denoiser computes it when asked in initialisation mode and from
  ExitInitializationMode on), equal to row 1.

The last input row is set before a step that the run does not take (its stop time is
t_(N-1), the last row's time): the inputs and outputs have the same times, N rows each. An array
variable is one column named after it, its values separated by spaces in each cell (``1.5 2.5
3.5``: fmusim's input and output format, which fmpy's ``read_csv`` reads too). Numbers are
written with Python's ``repr`` (the shortest text that reads back to the same double: equal bit
for bit), Booleans as 0 / 1.

>>> from gyrodenoise.fmu.reference import reference_documents
>>> sorted(reference_documents("FogDenoiserNative"))
['FogDenoiserNative_in.csv', 'FogDenoiserNative_ref.csv']
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.denoiser import denoise
from gyrodenoise.fmu.variables import DEFAULT_STEP_SIZE_S, IMU_AXES, IMU_AXIS_NAMES
from gyrodenoise.simulator import simulate

N_SAMPLES = 800
RESTART_AT = 500
SEED = 7            # of the denoisers' input noise (the sensor uses its seed parameter's start value, 0)
SENSOR_CARD = "paper_fog"   # the sensors' card parameter's start value

#: FMU model name -> what it is ("denoiser", "sensor" or "imu")
KINDS = {
    "FogDenoiser": "denoiser", "FogDenoiserNative": "denoiser", "FogDenoiserNative3": "denoiser",
    "SimulatedFog": "sensor", "SimulatedFogNative": "sensor", "SimulatedFogNative3": "sensor",
    "FogDenoiserImuNative3": "imu", "FogDenoiserImuNative": "imu_xyz",
}


def _time():
    return np.arange(N_SAMPLES) * DEFAULT_STEP_SIZE_S


def _restarts():
    rs = np.zeros(N_SAMPLES, dtype=bool)
    rs[RESTART_AT] = True
    return rs


def _rate(axis):
    """A gyro axis's raw rate: a bias, a manoeuvre from 1.5 s on, white noise (deg/s)."""
    t = _time()
    rng = np.random.default_rng(SEED + axis)
    return ((0.5 + axis) + (3.0 - axis) * np.sin(2 * np.pi * (0.7 + 0.2 * axis) * t) * (t > 1.5)
            + 0.05 * rng.standard_normal(N_SAMPLES))


def sensor_sample_rows(n):
    """The input row each of a sensor's ``n`` samples is taken from under the convention:
    sample 0 from row 0 (initialisation), sample j >= 1 from row j - 1 (the step ending at t_j)."""
    return np.maximum(np.arange(n) - 1, 0)


def _denoiser_outputs(z, restarts):
    """A denoiser's output rows for the input rows ``z`` (n, or n x axes) and ``restarts``: row k + 1
    the filter's sample k, row 0 its first output (sample 0: row 0's alone, the filter is causal)."""
    fs = 1.0 / DEFAULT_STEP_SIZE_S
    y = np.empty(z.shape)
    if z.ndim == 1:
        y[1:] = denoise(z[:-1], fs, restarts=restarts[:-1])
    else:
        for j in range(z.shape[1]):
            y[1:, j] = denoise(z[:-1, j], fs, restarts=restarts[:-1])
    y[0] = y[1]
    return y


def reference_tables(kind):
    """(inputs, outputs) of the reference run of an FMU of ``kind`` ("denoiser", "sensor", "imu", "imu_xyz"):
    each a dict {column name: array of N_SAMPLES values (N_SAMPLES x n for an array variable)},
    the time first."""
    t, rs = _time(), _restarts()
    if kind == "denoiser":
        z = _rate(0)
        return ({"time": t, "raw_rate": z, "restart": rs},
                {"time": t, "filtered_rate": _denoiser_outputs(z, rs)})
    if kind == "imu":
        z = np.column_stack([_rate(j) for j in range(IMU_AXES)])
        return ({"time": t, "raw_rate": z, "restart": rs},
                {"time": t, "filtered_rate": _denoiser_outputs(z, rs)})
    if kind == "imu_xyz":       # the imu run, one column an axis (raw_rate_x, ...)
        ins, outs = reference_tables("imu")
        return ({"time": t, **{f"raw_rate_{a}": ins["raw_rate"][:, j] for j, a in enumerate(IMU_AXIS_NAMES)},
                 "restart": rs},
                {"time": t, **{f"filtered_rate_{a}": outs["filtered_rate"][:, j] for j, a in enumerate(IMU_AXIS_NAMES)}})
    if kind == "sensor":
        truth = 0.5 + 3.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 1.0)
        rows = sensor_sample_rows(N_SAMPLES)
        rec = simulate(SENSOR_CARD, N_SAMPLES, seed=0, true_rate_deg_s=truth[rows], restarts=rs[rows])
        return ({"time": t, "true_rate": truth, "restart": rs},
                {"time": t, "measured_rate": rec.rate_deg_s, "restarted": rs[rows]})
    raise ValueError(f"unknown reference kind {kind!r}")


def _cell(value, is_bool):
    if np.ndim(value):
        return " ".join(_cell(v, is_bool) for v in value)
    return str(int(value)) if is_bool else repr(float(value))


def to_csv(table):
    """The CSV text of ``table`` ({column: values}): a header line, numbers as ``repr``, an
    array variable's values separated by spaces in its one cell."""
    names = list(table)
    cols = [np.asarray(table[n]) for n in names]
    lines = [",".join(names)]
    for i in range(len(cols[0])):
        lines.append(",".join(_cell(c[i], c.dtype == bool) for c in cols))
    return "\n".join(lines) + "\n"


def reference_documents(model):
    """{file name in the FMU's documentation/ folder: bytes}: ``<model>_in.csv`` and
    ``<model>_ref.csv``; {} for a model without a reference run."""
    kind = KINDS.get(model)
    if kind is None:
        return {}
    inputs, outputs = reference_tables(kind)
    return {f"{model}_in.csv": to_csv(inputs).encode(), f"{model}_ref.csv": to_csv(outputs).encode()}
