"""The denoiser as a thin class over the core, and the batch function.

:class:`Denoiser` keeps the parameter and state buffers of one gyro axis and
offers both speeds: :meth:`Denoiser.step` (one sample, used by the FMU and
live links) and :meth:`Denoiser.process` (the batch loop, for arrays). Both
run the C core (``gyrodenoise/core/gdcore.c`` through the extension
:mod:`gyrodenoise.core._gdcore`) when it is built, else the plain-Python
kernels (:mod:`gyrodenoise.core.kernels`, the executable specification; same
numbers). They share the state, so a stream may mix them freely.
"""

from __future__ import annotations

from array import array
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import ArrayLike

from .core import kernels as K
from .core import methods

try:
    from .core import _gdcore as _C  # type: ignore[attr-defined]  # the C extension: no stub
    _C_MISSING = ""
except ImportError as exc:  # pragma: no cover - no compiler at install, or an FMU on another platform
    _C = None
    _C_MISSING = str(exc)


def core_name() -> str:
    """Which implementation runs the filter: ``"C"`` or ``"Python"``."""
    return "C" if _C is not None else "Python"


def core_fallback_reason() -> str:
    """Why the C core could not be imported ("" when it runs)."""
    return _C_MISSING


class Denoiser:
    """One gyro axis through one of the core's methods (default: ``motion``), sample by sample or in batches.

    Parameters are those of :func:`gyrodenoise.core.kernels.make_params`.

    Examples
    --------
    >>> d = Denoiser(sample_rate_hz=200.0, method="shakf", ar_order=3)
    >>> y = d.step(0.01, restart=False)
    """

    def __init__(self, sample_rate_hz: float = 200.0, method: str = "motion", ar_order: int = 3,
                 **kw: float | int | None) -> None:
        params = K.make_params(ar_order=ar_order, method=method, sample_rate_hz=sample_rate_hz, **kw)
        # float64 buffers the C core reads and writes in place (plain lists for
        # the Python kernels); ``state`` indexes like a list either way
        self.params = array("d", params) if _C is not None else params
        self.state = self._buffer(K.init_state(params))
        self.sample_rate_hz = float(sample_rate_hz)
        self._step = _C.step if _C is not None else K.step

    @staticmethod
    def _buffer(values):
        return array("d", values) if _C is not None else [float(v) for v in values]

    # -- per-sample path
    def step(self, rate_deg_s: float, restart: bool = False) -> float:
        """Filter one sample (deg/s); ``restart`` marks a gyro restart."""
        return self._step(self.params, self.state, float(rate_deg_s), bool(restart))

    def reset(self) -> None:
        """Forget everything (as at construction)."""
        self.state = self._buffer(K.init_state(list(self.params)))

    # -- batch path
    def process(self, rate_deg_s: ArrayLike, restarts: ArrayLike | None = None,
                compiled: bool = True) -> np.ndarray:
        """Filter an array, continuing the state; returns a numpy array."""
        from .core import batch
        out, st = batch.run(self.params, self.state, rate_deg_s, restarts, compiled=compiled)
        self.state = self._buffer(st.tolist())
        return out

    # -- readouts
    @property
    def order(self) -> int:
        return int(self.params[K.P_ORDER])

    @property
    def phi(self) -> list[float]:
        """Current AR coefficients phi_1..phi_n (Eq. 4)."""
        return K.phi(self.params, self.state)

    @property
    def c(self) -> float:
        """Current constant term c of the improved AR model (Eq. 4), deg/s (0.0
        for motion and lowpass, which identify no AR model)."""
        return K.rls_c(self.params, self.state)

    @property
    def R_hat(self) -> float:
        """Current measurement-noise variance estimate, (deg/s)^2 (motion: the
        sensor's white-noise estimate from the 4th differences, or the spectral
        noise floor where that is more than 1.5x lower: kernels.motion_step)."""
        return float(self.state[K.S_R])

    @property
    def q_hat(self) -> float:
        """Current process-noise variance estimate, (deg/s)^2 (motion: the
        variance q of the rate increment per sample)."""
        return float(self.state[K.S_Q])

    @property
    def innovation(self) -> float:
        """Last innovation v_k = z_k - H X_pred, deg/s."""
        return float(self.state[K.S_INNOV])

    @property
    def bias_hat(self) -> float:
        """The gyro bias removed from the output by bias tracking (``bias_tracking=1``, method
        motion), deg/s; 0.0 when it is off (docs/method/bias.md)."""
        return K.bias_hat(self.params, self.state)

    @property
    def converged(self) -> bool:
        """True once the AR model has converged since the last restart."""
        return self.state[K.S_CONV] == 1.0

    @property
    def n_divergence_resets(self) -> int:
        """How many times the criterion of Eq. (32) restarted d_k."""
        return int(self.state[K.S_NRESET])

    @property
    def n_rejected(self) -> int:
        """Samples rejected by the outlier gate (``outlier_sigma`` > 0) so far."""
        return int(self.state[K.S_NREJ])

    @property
    def n_reopened(self) -> int:
        """Times a run of ``outlier_run`` rejections re-opened the filter."""
        return int(self.state[K.S_NREOPEN])

    def get_state(self) -> list[float]:
        """A copy of the full state (a list of floats) for save/restore."""
        return [float(v) for v in self.state]

    def set_state(self, state: list[float]) -> None:
        if len(state) != len(self.state):
            raise ValueError(f"state has {len(state)} values, expected {len(self.state)}")
        self.state = self._buffer(state)


def denoise(rate_deg_s: ArrayLike, sample_rate_hz: float, method: str = "motion", ar_order: int = 3,
            restarts: ArrayLike | None = None, zero_phase: bool = False, offline: bool = False,
            **kw: float | int | None) -> np.ndarray:
    """Denoise a gyro record with one of the core's methods (default: ``motion``).

    Parameters
    ----------
    rate_deg_s : array_like
        Raw angular rate, deg/s.
    sample_rate_hz : float
        Sample rate, Hz.
    method : str
        One of :data:`gyrodenoise.core.methods.METHODS`: "motion" (default) follows
        manoeuvres and averages at rest; "shakf" is the modified Sage-Husa AKF of the
        paper (Section 3.2.3), with ``outlier_sigma=0`` exactly the paper's filter;
        "lowpass" a causal Butterworth (``cutoff_hz``, ``order``); "one_euro" the
        1-euro filter (``min_cutoff_hz``, ``beta``, ``d_cutoff_hz``). See
        :func:`gyrodenoise.core.kernels.make_params`.
    ar_order : int
        Order n of the improved AR(n) model (Eq. 4).
    restarts : array_like of bool, optional
        True where the gyro restarted (re-identifies the model there).
    zero_phase : bool
        ``method="lowpass"`` only, for offline records: filter forwards, then
        backwards (squared magnitude response, no phase lag), each run of
        samples between restarts on its own.
    offline : bool
        ``method="motion"`` only, for whole records: each run between restarts
        smoothed by the two-filter smoother of the bank's models (no lag;
        :func:`gyrodenoise.core.batch.run_offline`).
        ``Denoiser.step``, the FMUs and live links stay causal.
    **kw
        Further parameters of :func:`gyrodenoise.core.kernels.make_params`, e.g.
        ``max_motion_hz`` (``method="motion"``, the rigid-body option for frames
        that vibrate: content above that band counts as error; offline, its
        low-pass runs zero-phase).

    Returns
    -------
    ndarray
        Filtered rate, deg/s (the raw sample during each warm-up).
    """
    import numpy as np

    from .core import batch
    p = K.make_params(ar_order=ar_order, method=method,
                      sample_rate_hz=sample_rate_hz, **kw)
    for form, on in (("zero_phase", zero_phase), ("smoother", offline)):
        owner = next(m.name for m in methods.METHODS if m.offline == form)
        if on and method != owner:
            raise ValueError(f"{methods.OFFLINE_FORMS[form][0]} applies to method={owner!r} only, not {method!r}")
    if offline and p[K.P_BIAS] > 0.0:
        # bias tracking offline: the causal run's bias (what it removed after each sample) off
        # the samples, then the smoother without it (docs/method/bias.md)
        _, hat = run_with_bias(p, rate_deg_s, restarts)
        p = list(p)
        p[K.P_BIAS] = 0.0
        return batch.run_offline(p, np.asarray(rate_deg_s, dtype=np.float64) - hat, restarts)
    if offline:
        return batch.run_offline(p, rate_deg_s, restarts)
    out, _ = batch.run(p, K.init_state(p), rate_deg_s, restarts)
    if zero_phase:
        rs = np.zeros(out.shape, dtype=bool) if restarts is None else np.asarray(restarts, dtype=bool)
        back, _ = batch.run(p, K.init_state(p), out[::-1], np.r_[rs[1:], False][::-1])
        out = back[::-1].copy()
    return out


def run_with_bias(params: list[float], rate_deg_s: ArrayLike,
                  restarts: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The causal run of parameters ``params`` from a fresh state: (output, the bias that bias
    tracking removed after each sample, ``Denoiser.bias_hat``), both deg/s. The output is the
    filter's clamped value less that bias: the clamped value is ``output + bias``, inside the raw
    samples' range since the last restart (docs/method/bias.md)."""
    from .core import batch
    out, _, hat = batch.run(params, K.init_state(params), rate_deg_s, restarts, trace_index=K.bias_index(params))
    return out, hat
