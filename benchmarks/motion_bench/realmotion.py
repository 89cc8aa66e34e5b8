"""Real moving gyros against a motion reference.

No per-sample true rate exists on real data: each method's output is
integrated into orientation over windows (0.1 s and 1 s) and compared with the
reference's rotation over the same windows. The error of a window is the angle
of q_gyro^-1 * q_ref (deg), where q_gyro is the body-frame rotation the gyro
output integrates to (exact exponential per sample, rate held over the sample)
and q_ref = q_ref(t0)^-1 q_ref(t1) the reference's. A method's figure is the
RMS of that angle over the windows, and its ratio to raw's.

Datasets (``/work/shared/data/motion``, README there):

* BROAD (Laidig et al. 2021): 285.7 Hz MEMS gyro, OptiTrack orientation in the
  IMU frame. Rest bias = the gyro's mean over the first rest segment (movement
  flag false from the start), removed before any filter. Windows start where
  ``movement`` is true and have a valid reference at both ends.
* PSINS car: 100 Hz MEMS increments against a FOG INS's attitude at 10 Hz
  (pitch, roll, yaw; ENU nav frame, PSINS ``a2mat``: Cnb = Rz(yaw) Rx(pitch)
  Ry(roll)). The MEMS bias ``eb0`` of the .mat is removed first (no rest segment).
* Quadrotor (Hurwitz & Klein 2023): four Xsens DOT at 120 Hz against the DJI
  autopilot's heading/pitch/roll at 10 Hz (NED, Rz Ry Rx, 0.1 deg steps). No
  rest: the gyro's bias is not removed.

Unknown timing and mounting are estimated once, on raw, and applied to every
method alike: the integer gyro-sample offset minimising the raw error (BROAD:
+-5 samples; the others: +-0.6 s, on the frame-invariant rotation angles of 1 s
windows), and for the car and quadrotor a constant mounting rotation (Kabsch on
the 1 s rotation vectors), then the sub-sample part of the offset (the
reference slerped by -0.5..0.5 gyro samples).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from benchmarks._data import SHARED_DATA
from benchmarks._jit import njit
from benchmarks.motion_bench import baselines as B


MOTION_DIR = SHARED_DATA / "motion"
WINDOWS_S = (0.1, 1.0)


# ------------------------------------------------------------------ quaternions (w, x, y, z)
def qmul(a, b):
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def qconj(q):
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qangle_deg(q):
    q = np.asarray(q, dtype=float)
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0])))


def qrotvec(q):
    """Rotation vector (rad) of unit quaternions."""
    q = np.asarray(q, dtype=float)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    s = np.linalg.norm(q[..., 1:], axis=-1)
    ang = 2.0 * np.arctan2(s, q[..., 0])
    scale = np.where(s > 1e-15, ang / np.maximum(s, 1e-300), 2.0)
    return q[..., 1:] * scale[..., None]


@njit
def _integrate(rate_rad_s, dt, starts, ends, out):
    for i in range(starts.size):
        w, x, y, z = 1.0, 0.0, 0.0, 0.0
        for k in range(starts[i], ends[i]):
            gx = rate_rad_s[k, 0]
            gy = rate_rad_s[k, 1]
            gz = rate_rad_s[k, 2]
            nrm = math.sqrt(gx * gx + gy * gy + gz * gz)
            half = 0.5 * nrm * dt
            if nrm > 0.0:
                s = math.sin(half) / nrm
                bw, bx, by, bz = math.cos(half), gx * s, gy * s, gz * s
            else:
                bw, bx, by, bz = 1.0, 0.0, 0.0, 0.0
            w, x, y, z = (w * bw - x * bx - y * by - z * bz, w * bx + x * bw + y * bz - z * by,
                          w * by - x * bz + y * bw + z * bx, w * bz + x * by - y * bx + z * bw)
        n = math.sqrt(w * w + x * x + y * y + z * z)
        out[i, 0] = w / n
        out[i, 1] = x / n
        out[i, 2] = y / n
        out[i, 3] = z / n


def integrate_windows(rate_deg_s, sample_rate_hz, starts, ends):
    """Body-frame rotation (quaternions, M x 4) integrating samples [starts[i], ends[i])."""
    out = np.empty((len(starts), 4))
    _integrate(np.ascontiguousarray(np.radians(rate_deg_s), dtype=float), 1.0 / float(sample_rate_hz),
               np.asarray(starts, dtype=np.int64), np.asarray(ends, dtype=np.int64), out)
    return out


def quat_from_euler(seq, angles_rad):
    """Quaternions (w, x, y, z) of intrinsic Euler rotations (scipy's upper-case ``seq``)."""
    from scipy.spatial.transform import Rotation
    xyzw = Rotation.from_euler(seq, angles_rad).as_quat()
    return np.column_stack([xyzw[:, 3], xyzw[:, :3]])


# ------------------------------------------------------------------ trials
@dataclass
class Trial:
    name: str
    dataset: str
    sample_rate_hz: float
    rate_deg_s: np.ndarray          # N x 3, bias removed where known
    ref_quat: np.ndarray            # M x 4, body-to-reference-frame orientation (NaN: lost)
    ref_index: np.ndarray           # M: gyro sample index at each reference time (before offset)
    valid_start: np.ndarray         # M bool: a window may start at this reference sample
    offset_search: int              # +- gyro samples searched for the time offset
    mounting_known: bool
    notes: list = field(default_factory=list)
    offset: int = 0                 # estimated (gyro samples; positive: gyro later than reference)
    frac: float = 0.0               # sub-sample part of the offset (gyro samples, -0.5..0.5)
    mounting: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))


def _first_rest_bias(gyr_deg_s, movement):
    end = int(np.argmax(movement)) if movement.any() else movement.size
    if end < 10:
        raise ValueError("no rest segment at the start of the trial")
    return gyr_deg_s[:end].mean(axis=0), end


def load_broad(path):
    import h5py
    with h5py.File(path, "r") as f:
        fs = float(f.attrs["sampling_rate"])
        gyr = np.degrees(f["imu_gyr"][()])
        quat = f["opt_quat"][()]
        movement = f["movement"][()].astype(bool)
    bias, rest_end = _first_rest_bias(gyr, movement)
    n = gyr.shape[0]
    t = Trial(Path(path).stem, "BROAD", fs, gyr - bias, quat, np.arange(n), movement & np.all(np.isfinite(quat), 1),
              offset_search=5, mounting_known=True)
    t.notes.append(f"rest bias ({', '.join(f'{b:.3f}' for b in bias)}) deg/s from the first {rest_end / fs:.1f} s")
    return t


def load_psins_car(folder):
    folder = Path(folder)
    import scipy.io as sio
    imu = np.loadtxt(folder / "transfer_align_mems_imu_100Hz.csv", delimiter=",", skiprows=1)
    avp = np.loadtxt(folder / "transfer_align_fog_ins_avp_10Hz.csv", delimiter=",", skiprows=1)
    mat = sio.loadmat(folder / "transfer_align_fog_mems.mat")
    fs = 1.0 / np.median(np.diff(imu[:, 0]))
    eb0 = np.degrees(mat["eb0"].ravel())
    rate = np.degrees(imu[:, 1:4]) * fs - eb0
    # increment k covers (t_k - dt, t_k]: the sample whose interval starts at time t is k = t fs + 1
    t0 = imu[0, 0]
    idx = np.round((avp[:, 0] - t0) * fs).astype(np.int64) + 1
    quat = quat_from_euler("ZXY", np.column_stack([avp[:, 3], avp[:, 1], avp[:, 2]]))
    t = Trial("psins_car", "PSINS car", fs, rate, quat, idx, np.ones(len(idx), bool),
              offset_search=int(0.6 * fs), mounting_known=False)
    t.notes.append(f"MEMS bias eb0 ({', '.join(f'{b:.3f}' for b in eb0)}) deg/s of the .mat removed")
    return t


def load_quadrotor(path_dir, imu):
    import csv
    path_dir = Path(path_dir)
    with open(path_dir / f"IMU_{imu}.csv") as fh:
        rows = list(csv.reader(fh))
    head = [h.strip() for h in rows[0]]
    a = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=float)
    ti = a[:, head.index("time")]
    gyr = a[:, [head.index("Gyr_X"), head.index("Gyr_Y"), head.index("Gyr_Z")]]
    with open(path_dir / "GT.csv") as fh:
        rows = list(csv.reader(fh))
    head = [h.strip() for h in rows[0]]
    g = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=float)
    tg = g[:, head.index("time")]
    eul = np.radians(np.column_stack([g[:, head.index("compass_heading(degrees)")],
                                      g[:, head.index("pitch(degrees)")], g[:, head.index("roll(degrees)")]]))
    fs = 1.0 / np.median(np.diff(ti))
    idx = np.round((tg - ti[0]) * fs).astype(np.int64)
    quat = quat_from_euler("ZYX", eul)
    return Trial(f"{path_dir.name}_imu{imu}", "quadrotor", fs, gyr, quat, idx, np.ones(len(idx), bool),
                 offset_search=int(0.6 * fs), mounting_known=False)


def available_trials(root=MOTION_DIR):
    """(name, loader) of every trial found under ``root`` (none when the data is absent)."""
    root = Path(root)
    out = []
    for p in sorted((root / "broad").glob("*.hdf5")):
        out.append((p.stem, lambda p=p: load_broad(p)))
    if (root / "psins_car" / "transfer_align_mems_imu_100Hz.csv").is_file():
        out.append(("psins_car", lambda: load_psins_car(root / "psins_car")))
    for d in sorted((root / "quadrotor_4imu").glob("path_*")):
        for k in range(1, 5):
            if (d / f"IMU_{k}.csv").is_file():
                out.append((f"{d.name}_imu{k}", lambda d=d, k=k: load_quadrotor(d, k)))
    return out


# ------------------------------------------------------------------ windows and errors
def windows(trial, window_s, offset=None):
    """(starts, ends, j0, j1): gyro sample ranges and reference indices of the
    non-overlapping windows of ``window_s``."""
    offset = trial.offset if offset is None else offset
    ref_dt = np.median(np.diff(trial.ref_index)) / trial.sample_rate_hz
    w = max(1, int(round(window_s / ref_dt)))
    j0 = np.arange(0, len(trial.ref_index) - w, w)
    j1 = j0 + w
    ok = trial.valid_start[j0] & np.all(np.isfinite(trial.ref_quat[j1]), axis=1) \
        & np.all(np.isfinite(trial.ref_quat[j0]), axis=1)
    if trial.dataset == "BROAD":
        ok &= trial.valid_start[j1]
    starts = trial.ref_index[j0] + offset
    ends = trial.ref_index[j1] + offset
    ok &= (starts >= 0) & (ends <= trial.rate_deg_s.shape[0])
    return starts[ok], ends[ok], j0[ok], j1[ok]


def qslerp(a, b, u):
    """Spherical interpolation from a to b by fraction u (rows)."""
    d = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(d < 0, -b, b)
    rel = qmul(qconj(a), b)
    rv = qrotvec(rel) * np.asarray(u, dtype=float)[..., None]
    ang = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * ang
    sinc = np.where(ang > 1e-15, np.sin(half) / np.maximum(ang, 1e-300), 0.5)
    return qmul(a, np.concatenate([np.cos(half), rv * sinc], axis=-1))


def ref_at(trial, j, frac=None):
    """Reference orientation at reference sample j shifted by ``frac`` gyro samples
    (slerp to the neighbouring reference sample; the sub-sample part of the offset)."""
    frac = trial.frac if frac is None else frac
    q = trial.ref_quat[j]
    if frac == 0.0:
        return q
    step = np.median(np.diff(trial.ref_index))          # gyro samples per reference sample
    u = frac / step
    jn = np.clip(j + (1 if u > 0 else -1), 0, len(trial.ref_quat) - 1)
    return qslerp(q, trial.ref_quat[jn], np.full(len(j), abs(u)))


def ref_relative(trial, j0, j1, frac=None):
    """Reference rotation over each window in the gyro frame."""
    rel = qmul(qconj(ref_at(trial, j0, frac)), ref_at(trial, j1, frac))
    m = trial.mounting
    return qmul(qmul(qconj(m), rel), m)


def window_errors_deg(trial, rate_deg_s, window_s, offset=None, frac=None):
    starts, ends, j0, j1 = windows(trial, window_s, offset)
    if frac is not None or trial.frac != 0.0:     # the shifted neighbour must exist too
        keep = (j0 > 0) & (j1 < len(trial.ref_quat) - 1)
        keep &= np.all(np.isfinite(trial.ref_quat[np.clip(j0 - 1, 0, None)]), 1)
        keep &= np.all(np.isfinite(trial.ref_quat[np.clip(j1 + 1, None, len(trial.ref_quat) - 1)]), 1)
        keep &= np.all(np.isfinite(trial.ref_quat[np.clip(j0 + 1, None, len(trial.ref_quat) - 1)]), 1)
        keep &= np.all(np.isfinite(trial.ref_quat[np.clip(j1 - 1, 0, None)]), 1)
        starts, ends, j0, j1 = starts[keep], ends[keep], j0[keep], j1[keep]
    q = integrate_windows(rate_deg_s, trial.sample_rate_hz, starts, ends)
    return qangle_deg(qmul(qconj(q), ref_relative(trial, j0, j1, frac)))


def rms(x):
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _kabsch(a, b):
    """Rotation quaternion R minimising sum |a_i - R b_i|^2 (a, b: M x 3)."""
    from scipy.spatial.transform import Rotation
    rot, _ = Rotation.align_vectors(a, b)
    xyzw = rot.as_quat()
    return np.r_[xyzw[3], xyzw[:3]]


def calibrate(trial):
    """Estimate the time offset (and the mounting when unknown) on raw; in place."""
    rate = trial.rate_deg_s
    offs = np.arange(-trial.offset_search, trial.offset_search + 1)
    if trial.mounting_known:
        errs = [rms(window_errors_deg(trial, rate, WINDOWS_S[0], o)) for o in offs]
        trial.offset = int(offs[int(np.argmin(errs))])
        return _fractional(trial, WINDOWS_S[0])
    # frame-invariant first: rotation angles over 1 s windows
    costs = []
    for o in offs:
        s, e, j0, j1 = windows(trial, 1.0, o)
        ang_g = qangle_deg(integrate_windows(rate, trial.sample_rate_hz, s, e))
        ang_r = qangle_deg(qmul(qconj(trial.ref_quat[j0]), trial.ref_quat[j1]))
        costs.append(rms(ang_g - ang_r))
    trial.offset = int(offs[int(np.argmin(costs))])
    s, e, j0, j1 = windows(trial, 1.0)
    g = qrotvec(integrate_windows(rate, trial.sample_rate_hz, s, e))
    r = qrotvec(qmul(qconj(trial.ref_quat[j0]), trial.ref_quat[j1]))
    # g ~ M^-1 r M  <=>  r = M g M^-1: the rotation taking gyro-frame vectors to the reference frame
    trial.mounting = _kabsch(r, g)
    # refine the offset with the full error, now that the frames agree
    fine = np.arange(trial.offset - 3, trial.offset + 4)
    errs = [rms(window_errors_deg(trial, rate, 1.0, o)) for o in fine]
    trial.offset = int(fine[int(np.argmin(errs))])
    return _fractional(trial, 1.0)


def _fractional(trial, window_s):
    """Sub-sample offset: a lag of half a sample is 0.5 deg of error at 300 deg/s
    on 285 Hz data, enough for a lagging filter to look better than raw."""
    grid = np.linspace(-0.5, 0.5, 21)
    trial.frac = 0.0
    errs = [rms(window_errors_deg(trial, trial.rate_deg_s, window_s, frac=f)) for f in grid]
    trial.frac = float(grid[int(np.argmin(errs))])
    return trial


def apply_per_axis(fn, rate_deg_s, fs):
    return np.column_stack([np.asarray(fn(np.ascontiguousarray(rate_deg_s[:, i]), fs), dtype=float)
                            for i in range(rate_deg_s.shape[1])])


def tuned_butter(trial, window_s, orders=(1, 2), n_grid=14):
    """Causal Butterworth tuned against the reference (an oracle): the cutoff and
    order with the lowest RMS window error at ``window_s``."""
    fs = trial.sample_rate_hz
    best = (math.inf, None, None)
    for order in orders:
        for fc in np.geomspace(0.5, 0.45 * fs, n_grid):
            y = np.column_stack([B.butter(x, fs, order, fc) for x in trial.rate_deg_s.T])
            e = rms(window_errors_deg(trial, y, window_s))
            if e < best[0]:
                best = (e, {"order": order, "cutoff_hz": float(fc)}, y)
    return best[1], best[2]
