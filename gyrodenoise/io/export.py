"""Export the Allan noise terms in the conventions other tools read.

Two targets, both continuous-time, SI, per axis:

Kalibr ``imu.yaml`` (ethz-asl/kalibr wiki, "IMU Noise Model" and "YAML
formats"):

* ``gyroscope_noise_density`` [rad/s/sqrt(Hz)] -- the white rate noise
  strength sigma_g, i.e. the angle random walk N in rad/sqrt(s)
  (N [deg/sqrt(h)] * pi/180 / 60).
* ``gyroscope_random_walk`` [rad/s^2/sqrt(Hz)] -- the strength of the white
  noise driving the bias random walk, i.e. the rate random walk K in
  rad/s^1.5 (K [deg/h^1.5] * pi/180 / 3600^1.5).
* ``update_rate`` [Hz] and ``rostopic``. Kalibr turns the densities into
  discrete sample sigmas with sqrt(update_rate); its wiki notes this assumes
  an ideal anti-alias decimation -- a subsampled gyro does not obey it.
* Kalibr's camera-IMU calibration also requires ``accelerometer_noise_density``
  and ``accelerometer_random_walk``. A gyro record cannot give them, so they
  are written as commented placeholders that the user must fill in (writing
  ``null`` or a made-up number would be worse: the first fails obscurely, the
  second silently).
* Kalibr's model has no bias-instability (flicker) or quantization term; B and
  Q are listed in comments only. The Allan terms describe the sensor under
  lab conditions; the Kalibr wiki cautions that unmodelled effects
  (vibration, temperature, mechanics) make real data noisier, and users
  commonly inflate the values: ``inflate`` multiplies both densities
  (default 1, no inflation), and the factor is written in the file.

MATLAB ``gyroparams`` (Sensor Fusion and Tracking / Navigation Toolbox,
``imuSensor``; MathWorks example "Inertial Sensor Noise Analysis Using Allan
Variance", which builds ``gyroparams('NoiseDensity', N, 'RandomWalk', K,
'BiasInstability', B)`` from the same fit):

* ``NoiseDensity`` [(rad/s)/sqrt(Hz)] = N in rad/sqrt(s) (same as Kalibr's).
* ``RandomWalk`` [(rad/s)*sqrt(Hz)] = K in rad/s^1.5 (MathWorks writes the
  unit of the rate random walk this way; it is the same number as Kalibr's
  ``gyroscope_random_walk``).
* ``BiasInstability`` [rad/s] = the coefficient B of Eq. (40), *not* the Allan
  floor 0.664 B: the MathWorks example divides the floor by
  sqrt(2 ln2 / pi) = 0.664 before passing it. MATLAB simulates it as white
  noise through the filter ``BiasInstabilityCoefficients`` (a first-order
  low-pass by default), so its Allan plateau only approximates 0.664 B.

The MATLAB output is a ``.m`` script (not JSON): it runs as is in MATLAB and
leaves a ``gyroparams`` object named ``params`` in the workspace, and every
value carries its unit and origin in a comment; the numbers are printed with
17 significant digits so nothing is lost.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

from gyrodenoise.errors import InputError
from gyrodenoise.units import TERM_BY_SYMBOL

if TYPE_CHECKING:
    from gyrodenoise.analysis.allan import AllanResult

DEG = math.pi / 180.0
# ROS graph resource names: letters, digits, '_', '/' separators, optional leading
# '/' or '~' (no spaces, ':' or '#', which would also break the YAML line)
_ROS_NAME = re.compile(r"[/~]?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*")


def terms_to_si(terms: Mapping[str, float]) -> dict[str, float]:
    """The five Allan terms (spec units) in SI, per second.

    Parameters
    ----------
    terms : dict
        N deg/sqrt(h), B deg/h, K deg/h^1.5, R deg/h^2, Q deg (spec section 3).

    Returns
    -------
    dict
        ``N_rad_sqrt_s`` (= rad/s/sqrt(Hz)), ``B_rad_s``, ``K_rad_s1_5``
        (= rad/s^2/sqrt(Hz)), ``R_rad_s2``, ``Q_rad``.
    """
    si = lambda k: float(terms[k]) * DEG / TERM_BY_SYMBOL[k].to_spec  # noqa: E731
    return {"N_rad_sqrt_s": si("N"), "B_rad_s": si("B"), "K_rad_s1_5": si("K"), "R_rad_s2": si("R"),
            "Q_rad": si("Q")}


def _yaml_float(x: float) -> str:
    """10 significant digits, always written as a float (200.0, not 200)."""
    t = f"{float(x):.10g}"
    return t if any(ch in t for ch in ".en") else t + ".0"


#: how an exported value was obtained, by `AllanResult.exported_bounds`' word (the fit says nothing)
HOW_OBTAINED = {
    "upper_bound": ("UPPER BOUND written as the value (Kalibr needs a number): the record cannot resolve "
                    "this term; it is the largest value whose Allan slope stays within the measured curve "
                    "(+2 sigma) at every tau, so the sensor's is at most this"),
    "slope_point": ("slope-point read (IEEE 952 / MathWorks: the term's Allan slope through the curve's "
                    "point of that slope): the Eq. (40) fit missed its own points there")}


def _bound_note(bounds: Mapping[str, str] | None, name: str) -> str:
    how = HOW_OBTAINED.get((bounds or {}).get(name, "fit"))
    return f"; {how}" if how else ""


def kalibr_imu_yaml(terms: Mapping[str, float], update_rate_hz: float, rostopic: str = "/imu0",
                    bounds: Mapping[str, str] | None = None, inflate: float = 1.0, source: str = "") -> str:
    """Text of a Kalibr ``imu.yaml`` for the gyro (accelerometer keys to fill in).

    Parameters
    ----------
    terms : dict
        Allan terms in spec units.
    update_rate_hz : float
        The IMU rate the densities refer to (the record's sample rate).
    rostopic : str
    bounds : dict, optional
        Term -> "fit" / "upper_bound" (from `AllanResult`).
    inflate : float
        Factor applied to both densities (>= 1 usual; 1 = the fitted values).
    source : str
        Where the terms came from (a comment).
    """
    if not (update_rate_hz > 0 and math.isfinite(update_rate_hz)):
        raise ValueError(f"update_rate_hz must be > 0, got {update_rate_hz!r}")
    if not (inflate > 0 and math.isfinite(inflate)):
        raise ValueError(f"inflate must be > 0, got {inflate!r}")
    si = terms_to_si(terms)
    nd = si["N_rad_sqrt_s"] * inflate
    rw = si["K_rad_s1_5"] * inflate
    lines = [
        "# Kalibr IMU noise parameters (continuous time), written by gyrodenoise",
        f"# from the Allan fit of {source or 'a gyro record'} on {datetime.now(timezone.utc):%Y-%m-%d}.",
        f"# Allan terms: N = {terms['N']:.6g} deg/sqrt(h), B = {terms['B']:.6g} deg/h, "
        f"K = {terms['K']:.6g} deg/h^1.5, R = {terms['R']:.6g} deg/h^2, Q = {terms['Q']:.6g} deg",
        "# Kalibr models white noise + bias random walk only: B (bias instability), R and Q are",
        "# not representable and are left out.",
        f"# Inflation factor applied to both gyro densities: {inflate:g}",
        "#",
        "# Accelerometers: not measured by this gyro record. Kalibr requires these two keys;",
        "# fill them in from your accelerometer's Allan analysis or datasheet.",
        "# accelerometer_noise_density: FILL_ME  # m/s^2/sqrt(Hz)",
        "# accelerometer_random_walk:   FILL_ME  # m/s^3/sqrt(Hz)",
        "",
        "# Gyroscopes",
        f"gyroscope_noise_density: {nd:.10g}  # rad/s/sqrt(Hz){_bound_note(bounds, 'N')}",
        f"gyroscope_random_walk: {rw:.10g}  # rad/s^2/sqrt(Hz){_bound_note(bounds, 'K')}",
        "",
        f"rostopic: {rostopic}",
        f"update_rate: {_yaml_float(update_rate_hz)}  # Hz",
        "",
    ]
    return "\n".join(lines)


def matlab_gyroparams_script(terms: Mapping[str, float], bounds: Mapping[str, str] | None = None,
                             source: str = "") -> str:
    """Text of a MATLAB ``.m`` script that builds ``params = gyroparams(...)``."""
    si = terms_to_si(terms)
    nb = lambda k: (" UPPER BOUND: not resolved by the record." if bounds and bounds.get(k) == "upper_bound"  # noqa: E731
                    else "")
    return "\n".join([
        "% Gyroscope noise parameters for MATLAB's imuSensor, written by gyrodenoise",
        f"% from the Allan fit of {source or 'a gyro record'} on {datetime.now(timezone.utc):%Y-%m-%d}.",
        f"% Allan terms: N = {terms['N']:.6g} deg/sqrt(h), B = {terms['B']:.6g} deg/h, "
        f"K = {terms['K']:.6g} deg/h^1.5, R = {terms['R']:.6g} deg/h^2, Q = {terms['Q']:.6g} deg",
        "% BiasInstability is the coefficient B (Allan plateau / 0.664), as in the MathWorks",
        "% example 'Inertial Sensor Noise Analysis Using Allan Variance'. R and Q have no",
        "% gyroparams property and are not exported.",
        "params = gyroparams( ...",
        f"    'NoiseDensity', {si['N_rad_sqrt_s']:.17g}, ...    % (rad/s)/sqrt(Hz), angle random walk N.{nb('N')}",
        f"    'BiasInstability', {si['B_rad_s']:.17g}, ... % rad/s, bias instability B.{nb('B')}",
        f"    'RandomWalk', {si['K_rad_s1_5']:.17g});        % (rad/s)*sqrt(Hz), rate random walk K.{nb('K')}",
        "",
    ])


# ------------------------------------------------------------- CLI helpers
def add_export_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--kalibr-yaml``, ``--kalibr-rostopic``, ``--kalibr-inflate`` and
    ``--matlab`` to an argparse parser (the ``allan`` subcommand)."""
    g = parser.add_argument_group("export of the noise terms")
    g.add_argument("--kalibr-yaml", metavar="PATH", default=None,
                   help="also write a Kalibr imu.yaml (gyro densities; accelerometer keys left to fill in)")
    g.add_argument("--kalibr-rostopic", default="/imu0", help="rostopic written to imu.yaml (default /imu0)")
    g.add_argument("--kalibr-inflate", type=float, default=1.0, metavar="FACTOR",
                   help="multiply both Kalibr densities by FACTOR (default 1: the fitted values)")
    g.add_argument("--matlab", metavar="PATH.m", default=None,
                   help="also write a MATLAB script building gyroparams (NoiseDensity, BiasInstability, RandomWalk)")


def export_from_args(args: argparse.Namespace, allan_result: AllanResult) -> list[str]:
    """Write the files asked for by `add_export_options`; returns their paths.

    Raises
    ------
    InputError
        One line naming the option or path and what is wrong.
    """
    check_export_args(args)
    written: list[str] = []
    source = str(getattr(args, "input", "") or "")
    terms, bounds = allan_result.exported_terms, allan_result.exported_bounds
    if getattr(args, "kalibr_yaml", None):
        text = kalibr_imu_yaml(terms, allan_result.sample_rate_hz, rostopic=args.kalibr_rostopic,
                               bounds=bounds, inflate=args.kalibr_inflate, source=source)
        written.append(_write(args.kalibr_yaml, text))
    if getattr(args, "matlab", None):
        written.append(_write(args.matlab, matlab_gyroparams_script(terms, bounds, source)))
    return written


def check_export_args(args: argparse.Namespace) -> None:
    """The export options of `add_export_options` (a ROS topic name, a positive inflation,
    folders that exist): one-line InputError, so that a command refuses them before it
    reads its input."""
    if getattr(args, "kalibr_yaml", None):
        topic = args.kalibr_rostopic
        if not _ROS_NAME.fullmatch(topic or ""):
            raise InputError(f"--kalibr-rostopic {topic!r} is not a ROS topic name "
                             "(letters, digits, '_' and '/', e.g. /imu0)")
        f = args.kalibr_inflate
        if not (f > 0 and math.isfinite(f)):
            raise InputError(f"--kalibr-inflate must be a positive number, got {f!r}")
    for path in (getattr(args, "kalibr_yaml", None), getattr(args, "matlab", None)):
        if path and not Path(path).resolve().parent.is_dir():
            raise InputError("cannot write: No such file or directory", str(path))


def _write(path: str | os.PathLike[str], text: str) -> str:
    p = Path(path)
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc.__class__.__name__}", str(p)) from None
    return str(p)


# ------------------------------------------------------- several axes, gyro and accel
@dataclass(frozen=True)
class AxisTerms:
    """The Allan terms of one axis for the exports: ``terms`` and ``bounds`` as
    `AllanResult`'s (spec units for a gyro; for an accelerometer the same numbers in
    m/s instead of deg: N m/s/sqrt(h), B m/s/h, K m/s/h^1.5)."""
    column: str
    accel: bool
    terms: Mapping[str, float]
    bounds: Mapping[str, str]

    def si(self) -> dict[str, float]:
        """`terms_to_si` of a gyro (rad); of an accelerometer the same in m (no deg -> rad)."""
        si = terms_to_si(self.terms)
        return {k: v / DEG for k, v in si.items()} if self.accel else si


def _largest(axes: Sequence[AxisTerms], key: str) -> tuple[float, AxisTerms]:
    """The largest SI value of ``key`` over ``axes`` and its axis (Kalibr takes one number
    for the three axes: the noisiest, so that none is overconfident)."""
    best = max(axes, key=lambda a: a.si()[key])
    return best.si()[key], best


def kalibr_imu_yaml_axes(axes: Sequence[AxisTerms], update_rate_hz: float, rostopic: str = "/imu0",
                         inflate: float = 1.0, source: str = "") -> str:
    """Text of a complete Kalibr ``imu.yaml`` from the gyro and accelerometer axes of one
    record: each density is the largest over its sensor's axes (named in a comment with
    every axis's value); accelerometer keys left to fill in when no accelerometer axis."""
    if not (update_rate_hz > 0 and math.isfinite(update_rate_hz)):
        raise ValueError(f"update_rate_hz must be > 0, got {update_rate_hz!r}")
    if not (inflate > 0 and math.isfinite(inflate)):
        raise ValueError(f"inflate must be > 0, got {inflate!r}")
    gyro = [a for a in axes if not a.accel]
    accel = [a for a in axes if a.accel]
    if not gyro:
        raise ValueError("no gyro axis")
    lines = ["# Kalibr IMU noise parameters (continuous time), written by gyrodenoise",
             f"# from the Allan fits of {source or 'a record'} on {datetime.now(timezone.utc):%Y-%m-%d}",
             f"# ({len(gyro)} gyro and {len(accel)} accelerometer axes); each density is the largest over the "
             f"axes (Kalibr takes one per sensor).",
             "# Kalibr models white noise + bias random walk only: B (bias instability), R and Q are left out.",
             f"# Inflation factor applied to all densities: {inflate:g}", "#"]
    for a in axes:
        si = a.si()
        u = ("m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)") if a.accel else ("rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)")
        word = {k: a.bounds.get(k, "fit").replace("_", " ").replace("slope point", "slope-point read")
                for k in ("N", "K")}
        lines.append(f"# {a.column}: noise density {si['N_rad_sqrt_s']:.6g} {u[0]} ({word['N']}), random walk "
                     f"{si['K_rad_s1_5']:.6g} {u[1]} ({word['K']})")
    lines.append("")
    for name, group, units in (("accelerometer", accel, ("m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)")),
                               ("gyroscope", gyro, ("rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)"))):
        lines.append(f"# {name.capitalize()}s")
        if not group:
            lines += ["# Not measured by this record: Kalibr requires these two keys; fill them in from",
                      f"# your {name}'s Allan analysis or datasheet.",
                      f"# {name}_noise_density: FILL_ME  # {units[0]}",
                      f"# {name}_random_walk:   FILL_ME  # {units[1]}", ""]
            continue
        nd, a_nd = _largest(group, "N_rad_sqrt_s")
        rw, a_rw = _largest(group, "K_rad_s1_5")
        lines += [f"{name}_noise_density: {nd * inflate:.10g}  # {units[0]}, {a_nd.column}"
                  f"{_bound_note(a_nd.bounds, 'N')}",
                  f"{name}_random_walk: {rw * inflate:.10g}  # {units[1]}, {a_rw.column}"
                  f"{_bound_note(a_rw.bounds, 'K')}", ""]
    lines += [f"rostopic: {rostopic}", f"update_rate: {_yaml_float(update_rate_hz)}  # Hz", ""]
    return "\n".join(lines)


def matlab_imu_params_script(axes: Sequence[AxisTerms], source: str = "") -> str:
    """Text of a MATLAB ``.m`` script that builds ``gyro = gyroparams(...)`` and, with
    accelerometer axes, ``accel = accelparams(...)`` for ``imuSensor`` (vector properties,
    one value per axis in the order of the columns)."""
    out = ["% IMU noise parameters for MATLAB's imuSensor, written by gyrodenoise",
           f"% from the Allan fits of {source or 'a record'} on {datetime.now(timezone.utc):%Y-%m-%d}.",
           "% BiasInstability is the coefficient B (Allan plateau / 0.664), as in the MathWorks example",
           "% 'Inertial Sensor Noise Analysis Using Allan Variance'; R and Q have no property.",
           "% One value per axis, in the order of the columns named."]
    for fn, accel, units in (("gyroparams", False, ("(rad/s)/sqrt(Hz)", "rad/s", "(rad/s)*sqrt(Hz)")),
                             ("accelparams", True, ("(m/s^2)/sqrt(Hz)", "m/s^2", "(m/s^2)*sqrt(Hz)"))):
        group = [a for a in axes if a.accel == accel]
        if not group:
            continue
        var = "accel" if accel else "gyro"
        vec = lambda key: "[" + " ".join(f"{a.si()[key]:.17g}" for a in group) + "]"  # noqa: E731
        upper = [f"{a.column} {k}" for a in group for k in "NBK" if a.bounds.get(k) == "upper_bound"]
        out += [f"% {var}: columns {', '.join(a.column for a in group)}"
                + (f"; UPPER BOUNDS (not resolved): {', '.join(upper)}" if upper else ""),
                f"{var} = {fn}( ...",
                f"    'NoiseDensity', {vec('N_rad_sqrt_s')}, ...    % {units[0]}",
                f"    'BiasInstability', {vec('B_rad_s')}, ... % {units[1]}",
                f"    'RandomWalk', {vec('K_rad_s1_5')});        % {units[2]}"]
    out.append("")
    return "\n".join(out)


def export_axes_from_args(args: argparse.Namespace, axes: Sequence[AxisTerms], sample_rate_hz: float) -> list[str]:
    """Write the files asked for by `add_export_options` from several axes; their paths."""
    check_export_args(args)
    written: list[str] = []
    source = str(getattr(args, "input", "") or "")
    if getattr(args, "kalibr_yaml", None):
        written.append(_write(args.kalibr_yaml, kalibr_imu_yaml_axes(
            axes, sample_rate_hz, rostopic=args.kalibr_rostopic, inflate=args.kalibr_inflate, source=source)))
    if getattr(args, "matlab", None):
        written.append(_write(args.matlab, matlab_imu_params_script(axes, source)))
    return written
