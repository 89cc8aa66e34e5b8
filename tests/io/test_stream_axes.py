"""The chunked reader over several axes (gyrodenoise.io.chunked.open_axes) against the
whole-array one (gyrodenoise.io.recording.read_axes), bit for bit: three gyro and three
accelerometer columns with a time column, a bridged and a restarting gap, a spike and a
saturation run, at tiny chunk sizes; and the files it leaves to the whole-array reader."""

from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.errors import InputError
from gyrodenoise.io.recording import read_axes

pytest.importorskip("pyarrow")
from gyrodenoise.io.chunked import open_axes  # noqa: E402

N = 2400


def imu_record(path, n: int = N, seed: int = 5, sep: str = ",", header=("gx", "gy", "gz", "ax", "ay", "az"),
               extra: str | None = None, accel_g: bool = False, time: bool = True) -> None:
    """time (s, 200 Hz: a bridged gap, a restarting gap), three gyro columns (deg/s: a spike
    in gx, a saturation run in gz), three accelerometer columns about gravity (m/s^2, or g)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 200.0
    keep = np.ones(n, bool)
    keep[[400, 401]] = False              # bridged
    keep[1500:1530] = False               # a restart
    t = t[keep]
    m = t.size
    g = rng.normal(0.0, 0.05, (3, m)).round(7)
    g[0, m // 3] = 40.0
    g[2, m // 2:m // 2 + 12] = g[2].max()
    a = rng.normal(0.0, 0.02, (3, m)).round(7) + np.array([[0.1], [-0.2], [9.81]])
    if accel_g:
        a = (a / 9.81).round(7)
    cols = ([t] if time else []) + list(g) + list(a)
    names = (["time"] if time else []) + list(header)
    if extra is not None:
        cols.append(rng.normal(0, 1, m).round(5))
        names.append(extra)
    with open(path, "w") as f:
        f.write(sep.join(names) + "\n")
        f.writelines(sep.join(repr(float(v)) for v in row) + "\n" for row in zip(*cols))


def _same(s, rec) -> None:
    assert s.notes == rec.notes
    assert s.sample_rate_hz == rec.sample_rate_hz and s.n == len(rec.time_s)
    assert [(a.column, a.kind, a.unit, a.unit_how, a.scale) for a in s.axes] == \
        [(a.column, a.kind, a.unit, a.unit_how, a.scale) for a in rec.axes]


@pytest.mark.parametrize("chunk", [1, 7, 500])
def test_six_axes_chunked_are_the_whole_record(tmp_path, chunk: int) -> None:
    p = tmp_path / "imu.csv"
    imu_record(p)
    rec = read_axes(p)
    assert rec.restarts is not None and rec.restarts.sum() == 1      # the restarting gap is in the model
    assert len(rec.axes) == 6 and any("spike" in n for n in rec.notes) and any("saturation" in n for n in rec.notes)
    with open_axes(p, chunk=chunk) as s:
        _same(s, rec)
        parts = list(s.axis_chunks(chunk))
        np.testing.assert_array_equal(np.concatenate([c[0] for c in parts]), rec.time_s)
        for i, ax in enumerate(rec.axes):
            np.testing.assert_array_equal(np.concatenate([c[1][i] for c in parts]), ax.values)
            np.testing.assert_array_equal(np.concatenate(list(s.values(i, chunk))), ax.values)
        got = [c[2] if c[2] is not None else np.zeros(len(c[0]), bool) for c in parts]
        np.testing.assert_array_equal(np.concatenate(got), rec.restarts)
        np.testing.assert_array_equal(s.restarts, rec.restarts)


@pytest.mark.parametrize("kw", [dict(rate_columns=["gx", "gy", "gz"]),
                                dict(rate_columns=["GY", "gz"], accel_columns=["az"], accel_unit="m/s^2"),
                                dict(rate_columns=["gx", "gy", "gz"], accel_columns=["ax", "ay", "az"],
                                     rate_scale=[2.0, 3.0, 0.5], accel_scale=0.25, accel_unit="g",
                                     rate_unit="rad/s")])
def test_columns_units_and_scales_as_the_whole_reader(tmp_path, kw) -> None:
    p = tmp_path / "imu.csv"
    imu_record(p, extra="temp")
    rec = read_axes(p, **kw)
    with open_axes(p, chunk=97, **kw) as s:
        _same(s, rec)
        for i, ax in enumerate(rec.axes):
            np.testing.assert_array_equal(np.concatenate(list(s.values(i, 97))), ax.values)


def test_detected_ros_names_and_no_time_column(tmp_path) -> None:
    p = tmp_path / "imu.csv"
    names = tuple(f"field.angular_velocity.{a}" for a in "xyz") + tuple(f"field.linear_acceleration.{a}"
                                                                        for a in "xyz")
    imu_record(p, header=names, time=False)
    rec = read_axes(p, sample_rate_hz=100.0)
    with open_axes(p, sample_rate_hz=100.0, chunk=13) as s:
        _same(s, rec)
        assert s.axes[0].unit == "rad/s"
        np.testing.assert_array_equal(np.concatenate([c[0] for c in s.axis_chunks(13)]), rec.time_s)


def test_refusals_are_the_whole_readers(tmp_path) -> None:
    p = tmp_path / "imu.csv"
    imu_record(p)
    text = p.read_text().splitlines(keepends=True)
    text[7] = text[7].replace(text[7].split(",")[3], "5e9", 1)    # gz beyond any gyro reading
    p.write_text("".join(text))
    with pytest.raises(InputError) as whole:
        read_axes(p)
    with pytest.raises(InputError) as chunked:
        open_axes(p, chunk=7)
    assert str(chunked.value) == str(whole.value)


def test_left_to_the_whole_reader(tmp_path) -> None:
    """Decimal commas, runs of spaces, an accelerometer in g read as m/s^2 (the reader's
    gravity check refuses it), a true_rate column beside one gyro axis: None or marked."""
    p = tmp_path / "imu.csv"
    imu_record(p, sep=";")
    p.write_text(p.read_text().replace(".", ","))
    assert open_axes(p) is None and len(read_axes(p).axes) == 6
    imu_record(p, sep="  ")
    assert open_axes(p) is None and len(read_axes(p).axes) == 6
    imu_record(p, accel_g=True)
    assert open_axes(p) is None
    with pytest.raises(InputError, match="gravity"):
        read_axes(p)
    imu_record(p, extra="true_rate")
    with open_axes(p, ["gx"], ["ax", "ay", "az"], chunk=7) as s:
        assert s.has_true


def test_gravity_count_is_the_median() -> None:
    """`_GravityCount` says inside exactly when the median of |a| is inside the band (and
    never inside when the median is not), odd and even counts, values on the band's edges."""
    from gyrodenoise.io.chunked import _GravityCount
    from gyrodenoise.io.recording import GRAVITY_M_S2
    rng = np.random.default_rng(0)
    lo, hi = GRAVITY_M_S2
    for _ in range(300):
        n = int(rng.integers(1, 12))
        norm = rng.choice([lo / 2, lo, 9.81, hi, hi * 2], n)
        g = _GravityCount()
        g.add([norm, np.zeros(n), np.zeros(n)])
        med = float(np.median(norm))
        if g.inside():
            assert lo <= med <= hi
        else:    # the counts may refuse a median that averages two values across an edge
            assert not (lo <= med <= hi) or (n % 2 == 0 and not lo <= np.sort(norm)[n // 2 - 1] <= hi
                                              or n % 2 == 0 and not lo <= np.sort(norm)[n // 2] <= hi)
