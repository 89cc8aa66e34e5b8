"""Recordings that are not text: ROS 1/2 bags and MCAP files (``sensor_msgs/Imu``) and
MATLAB ``.mat`` files, read into named columns that the recording reader
(:func:`gyrodenoise.io.recording.read_axes`) takes as it takes a CSV's.

* A bag (read by :func:`gyrodenoise.flightlog.rosbag.read_imu`, the flight-log side's
  reader, which the caller passes in): one ``sensor_msgs/Imu`` topic (``topic``; the only one when not given) gives
  ``time`` (the header stamps, int ns; the receive times when the stamps are unset),
  ``angular_velocity.x/y/z`` (rad/s) and ``linear_acceleration.x/y/z`` (m/s^2; left out
  when every message marks it absent, covariance[0] = -1), as REP 103 defines them.
* A ``.mat`` file: v5 (and older) through ``scipy.io.loadmat``, v7.3 (HDF5) through
  ``h5py`` (the ``mat`` extra: pip install 'gyrodenoise[mat]'). Every numeric variable (or the fields of the struct
  ``variable``) becomes columns: a vector its name, an n x 3 matrix ``name_x/y/z``, an
  n x k matrix ``name_1`` ... ``name_k`` (the longer side is the samples, so MATLAB's
  column-major 3 x n reads too); the columns of the most common length are kept, the
  others named in a note.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrodenoise.errors import InputError


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


@dataclass(frozen=True)
class Table:
    """Named columns of one length; ``row_name`` what a row is (message, row)."""
    columns: dict[str, np.ndarray]
    notes: tuple[str, ...]
    row_name: str


def read_container(path: str | os.PathLike[str], topic: str | None = None, variable: str | None = None,
                   bag_reader: Callable[..., Any] | None = None) -> Table:
    """The columns of a bag, an MCAP or a ``.mat`` file (module doc); InputError (one line).

    ``bag_reader(path, topic)``: the bag reader, :func:`gyrodenoise.flightlog.rosbag.read_imu`
    (passed in: this layer does not import the flight-log side)."""
    p = Path(path)
    if not p.exists():
        raise InputError("no such file", str(path))
    if p.suffix.lower() == ".mat":
        if topic is not None:
            raise InputError("--topic applies to ROS bags and MCAP files, not to a .mat file", str(path))
        return _read_mat(p, variable)
    if variable is not None:
        raise InputError("--variable applies to MATLAB .mat files, not to a bag", str(path))
    if bag_reader is None:
        raise InputError("a bag needs the bag reader: read_axes(..., bag_reader=gyrodenoise.flightlog.rosbag.read_imu)",
                         str(path))
    return _read_bag(p, topic, bag_reader)


def _read_bag(p: Path, topic: str | None, read_imu: Callable[..., Any]) -> Table:
    bag = read_imu(p, topic)
    if not bag.imu:
        raise InputError(f"no sensor_msgs/Imu topic (topics: {', '.join(bag.topics) or 'none'})", str(p))
    if len(bag.imu) > 1:
        raise InputError(f"{len(bag.imu)} sensor_msgs/Imu topics ({', '.join(t.topic for t in bag.imu)}): "
                         f"choose one with --topic", str(p))
    imu = bag.imu[0]
    n = len(imu)
    stamped = bool(np.any(imu.stamp_ns != imu.stamp_ns[0])) if n else False
    cols: dict[str, np.ndarray] = {"time": imu.stamp_ns if stamped else imu.receive_ns}
    for i, a in enumerate("xyz"):
        cols[f"angular_velocity.{a}"] = imu.angular_velocity[:, i]
    notes = [f"topic {imu.topic} of {p.name} ({bag.kind}{', ' + bag.storage if bag.storage else ''}): "
             f"{n:,} sensor_msgs/Imu messages, frame {imu.frame_id or '(none)'}; time from the "
             + ("header stamps" if stamped else "receive times (the header stamps are all equal)")]
    if imu.linear_acceleration_absent < n:
        for i, a in enumerate("xyz"):
            cols[f"linear_acceleration.{a}"] = imu.linear_acceleration[:, i]
    else:
        notes.append("linear_acceleration marked absent in every message (covariance[0] = -1): not read")
    if imu.angular_velocity_absent:
        notes.append(f"angular_velocity marked absent in {imu.angular_velocity_absent:,} messages: read as written")
    return Table(cols, tuple(notes), "message")


def _read_mat(p: Path, variable: str | None) -> Table:
    top = _load_mat(p)
    if variable is not None:
        if variable not in top:
            raise InputError(f"no variable {variable!r} (variables: {', '.join(sorted(top)) or 'none'})", str(p))
        top = {variable: top[variable]}
    flat: dict[str, np.ndarray] = {}
    for name, value in top.items():
        _flatten(name, value, flat)
    if not flat:
        raise InputError("no numeric variable", str(p))
    lengths = Counter(len(v) for v in flat.values() if len(v) >= 2)
    if not lengths:
        raise InputError("no variable of 2 samples or more", str(p))
    n = max(lengths, key=lambda k: (lengths[k], k))
    kept = {k: v for k, v in flat.items() if len(v) == n}
    left = sorted(k for k in flat if k not in kept)
    notes = [f"MATLAB file: {len(kept)} column(s) of {n:,} rows from its variables"]
    if left:
        notes.append(f"variables of another length left out: {', '.join(left[:8])}"
                     + (f", ... ({len(left)} in all)" if len(left) > 8 else ""))
    return Table(kept, tuple(notes), "row")


def _load_mat(p: Path) -> dict[str, Any]:
    """Top-level variables of a .mat file: v7.3 (HDF5, its signature at byte 0 or after
    MATLAB's 512-byte header) by h5py, older ones by scipy."""
    with open(p, "rb") as f:
        head = f.read(520)
    if HDF5_SIGNATURE in (head[:8], head[512:520]):
        try:
            import h5py
        except ImportError:
            raise InputError("a MATLAB v7.3 (HDF5) file needs h5py, not installed: pip install 'gyrodenoise[mat]'",
                             str(p)) from None
        try:
            with h5py.File(p, "r") as f:
                return {k: _h5_value(f[k]) for k in f if not k.startswith("#")}
        except OSError as exc:
            raise InputError(f"cannot read as a MATLAB v7.3 file: {exc}", str(p)) from None
    import scipy.io
    try:
        return {k: v for k, v in scipy.io.loadmat(str(p), squeeze_me=True, struct_as_record=False).items()
                if not k.startswith("__")}
    except (NotImplementedError, ValueError, TypeError, OSError) as exc:
        raise InputError(f"cannot read as a MATLAB file: {exc}", str(p)) from None


def _h5_value(obj: Any) -> Any:
    """A v7.3 dataset as an array in MATLAB's orientation (h5py shows it transposed), a
    group (struct) as a dict, a char array or a reference as None."""
    import h5py
    if isinstance(obj, h5py.Group):
        return {k: _h5_value(obj[k]) for k in obj if not k.startswith("#")}
    cls = obj.attrs.get("MATLAB_class", b"")
    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
    if cls in ("char", "cell", "struct") or obj.dtype.kind not in "iuf":
        return None
    return np.asarray(obj[()]).T


def _flatten(name: str, value: Any, out: dict[str, np.ndarray]) -> None:
    """Numeric columns of ``value`` (module doc) into ``out``; structs by their field names."""
    fields = getattr(value, "_fieldnames", None)
    if fields is not None:                       # scipy's mat_struct
        for f in fields:
            _flatten(f, getattr(value, f), out)
        return
    if isinstance(value, dict):
        for f, v in value.items():
            _flatten(f, v, out)
        return
    if value is None:
        return
    a = np.asarray(value)
    if a.dtype.kind not in "iuf" or a.ndim == 0 or a.ndim > 2:
        return
    if a.ndim == 2:
        if a.shape[1] > a.shape[0]:
            a = a.T
        if a.shape[1] == 1:
            a = a[:, 0]
    if a.ndim == 1:
        out[name] = a
        return
    k = a.shape[1]
    names = [f"{name}_{c}" for c in "xyz"] if k == 3 else [f"{name}_{j + 1}" for j in range(k)]
    for j, col in enumerate(names):
        out[col] = a[:, j]
