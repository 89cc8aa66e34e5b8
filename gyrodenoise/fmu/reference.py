"""Reference results carried by every FMU: an input CSV and the output CSV expected from it.

Laid out as the Modelica Reference-FMUs do (each model ships ``<Model>_in.csv`` with its input
signals and ``<Model>_ref.csv`` with the expected result; their FMU archives carry the model's
documentation and reference plot under ``documentation/``): every gyrodenoise FMU, FMI 2.0 and
3.0, native and pythonfmu, carries ``documentation/<Model>_in.csv`` and
``documentation/<Model>_ref.csv``. The expected outputs are produced by the library
(:func:`gyrodenoise.denoise` and :func:`gyrodenoise.simulate`), never by an FMU.

The run: :data:`N_SAMPLES` samples at the FMUs' default sample period (0.005 s), every parameter
at its start value, a restart at sample :data:`RESTART_AT` (the default warm-up is 1 s = 200
samples, so the run shows warm-up, filtering, a restart and filtering again). Row k holds the
time t_k = k * 0.005 s, the inputs set for sample k and the outputs of sample k: for a denoiser
the outputs read after the step [t_k, t_k + h] (inputs set before it); for a sensor the sample
at t_k (row 0: read after ExitInitializationMode with the inputs of row 0 set before it; row
k >= 1: read after the step [t_(k-1), t_k], the inputs of row k set before it). Numbers are
written with Python's ``repr`` (the shortest text that reads back to the same double: equal bit
for bit), Booleans as 0 / 1; an array variable's values are the columns ``name[1]``, ``name[2]``...

>>> from gyrodenoise.fmu.reference import reference_documents
>>> sorted(reference_documents("FogDenoiserNative"))
['FogDenoiserNative_in.csv', 'FogDenoiserNative_ref.csv']
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.denoiser import denoise
from gyrodenoise.fmu.variables import DEFAULT_STEP_SIZE_S, IMU_AXES
from gyrodenoise.simulator import simulate

N_SAMPLES = 800
RESTART_AT = 500
SEED = 7            # of the denoisers' input noise (the sensor uses its seed parameter's start value, 0)
SENSOR_CARD = "paper_fog"   # the sensors' card parameter's start value

#: FMU model name -> what it is ("denoiser", "sensor" or "imu")
KINDS = {
    "FogDenoiser": "denoiser", "FogDenoiserNative": "denoiser", "FogDenoiserNative3": "denoiser",
    "SimulatedFog": "sensor", "SimulatedFogNative": "sensor", "SimulatedFogNative3": "sensor",
    "FogDenoiserImuNative3": "imu",
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


def reference_tables(kind):
    """(inputs, outputs) of the reference run of an FMU of ``kind`` ("denoiser", "sensor", "imu"):
    each a dict {column name: array of N_SAMPLES values}, the time first."""
    t, rs = _time(), _restarts()
    fs = 1.0 / DEFAULT_STEP_SIZE_S
    if kind == "denoiser":
        z = _rate(0)
        return ({"time": t, "raw_rate": z, "restart": rs},
                {"time": t, "filtered_rate": denoise(z, fs, restarts=rs)})
    if kind == "imu":
        zs = [_rate(j) for j in range(IMU_AXES)]
        inputs = {"time": t, **{f"raw_rate[{j + 1}]": z for j, z in enumerate(zs)}, "restart": rs}
        outputs = {"time": t, **{f"filtered_rate[{j + 1}]": denoise(z, fs, restarts=rs) for j, z in enumerate(zs)}}
        return inputs, outputs
    if kind == "sensor":
        truth = 0.5 + 3.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 1.0)
        rec = simulate(SENSOR_CARD, N_SAMPLES, seed=0, true_rate_deg_s=truth, restarts=rs)
        return ({"time": t, "true_rate": truth, "restart": rs},
                {"time": t, "measured_rate": rec.rate_deg_s, "restarted": rs})
    raise ValueError(f"unknown reference kind {kind!r}")


def to_csv(table):
    """The CSV text of ``table`` ({column: values}): a header line, numbers as ``repr``."""
    names = list(table)
    cols = [np.asarray(table[n]) for n in names]
    lines = [",".join(names)]
    for i in range(len(cols[0])):
        lines.append(",".join(str(int(c[i])) if c.dtype == bool else repr(float(c[i])) for c in cols))
    return "\n".join(lines) + "\n"


def reference_documents(model):
    """{file name in the FMU's documentation/ folder: bytes}: ``<model>_in.csv`` and
    ``<model>_ref.csv``; {} for a model without a reference run."""
    kind = KINDS.get(model)
    if kind is None:
        return {}
    inputs, outputs = reference_tables(kind)
    return {f"{model}_in.csv": to_csv(inputs).encode(), f"{model}_ref.csv": to_csv(outputs).encode()}
