"""Simulating a card S times: through SimulatedFog.fmu (worker processes) or the core simulator."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gyrodenoise.console import log
from gyrodenoise.errors import InputError
from gyrodenoise.modelgap.cards import card_at_rate, text_at_rate
from gyrodenoise.modelgap.population import draw_unit


# ------------------------------------------------------------------ simulation
def _fmu_worker(fmu_path: str, card_text: str, seed: int, n: int, fs: float,
                restarts: list[bool] | None) -> np.ndarray | str:
    """Simulate one seed through SimulatedFog.fmu; returns the rates, or a one-line
    error message (str) instead of raising: FMU exceptions need not unpickle in the
    parent process, and a raise there would surface as a BrokenProcessPool."""
    try:
        return _fmu_simulate(fmu_path, card_text, seed, n, fs, restarts)
    except Exception as exc:        # noqa: BLE001 - returned as text to the parent
        msg = " ".join(str(exc).split()) or "no message"
        return f"{exc.__class__.__name__}: {msg}"


def _fmu_simulate(fmu_path: str, card_text: str, seed: int, n: int, fs: float,
                  restarts: list[bool] | None) -> np.ndarray:
    """Simulate one seed through SimulatedFog.fmu with fmpy FMU2Slave: sample 0 at
    fmi2ExitInitializationMode, then one step per sample (``gyrodenoise.simulate``'s
    numbers, bit for bit)."""
    from gyrodenoise.fmu import FmuInstance, _stepper
    fog = FmuInstance(fmu_path, f"fog{seed}")
    try:
        rs = [False] * n if restarts is None else [bool(v) for v in restarts]
        out = np.empty(n)
        if n == 0:
            return out
        # sample 0 is taken at fmi2ExitInitializationMode from the inputs set before it;
        # the step from t_(k-1) produces sample k (at its end) from the inputs set before it
        fog.initialize(card=card_text, seed=int(seed), true_rate=0.0, restart=rs[0])
        out[0] = fog.get("measured_rate")
        step = _stepper(fog, "true_rate", "restart", "measured_rate")
        h = 1.0 / fs
        for k in range(1, n):
            out[k] = step(0.0, rs[k], (k - 1) * h, h)
    finally:
        fog.free()
    return out


def fmu_path_for(fmu_dir: str | os.PathLike[str] | None = None, quiet: bool = False) -> Path:
    """SimulatedFog.fmu in ``fmu_dir`` (default build/), built when missing or stale."""
    from gyrodenoise import fmu as F
    d = Path(fmu_dir) if fmu_dir is not None else Path("build")
    path = d / "SimulatedFog.fmu"
    why = F.stale_reason(path)
    if why is not None:
        log(f"gyrodenoise: note: building {path} ({why})", quiet=quiet)
        F.build_fmu("SimulatedFog", d)
    return path


class Simulator:
    """Simulate a card text S times at a record's rate and length.

    ``engine="native"`` uses `gyrodenoise.simulator.simulate`;
    ``engine="fmu"`` steps SimulatedFog.fmu through fmpy in ``workers``
    processes (one FMU instance per process). A card whose noise terms carry a
    ``spread`` is simulated as one drawn unit per seed (`population.draw_unit`);
    a card without one, as written (bit for bit).
    """

    def __init__(self, n: int, fs: float, seeds: Iterable[int], engine: str = "native",
                 restarts: npt.ArrayLike | None = None, fmu_dir: str | os.PathLike[str] | None = None,
                 workers: int | None = None, quiet: bool = False, source: str = "<card>") -> None:
        if engine not in ("native", "fmu"):
            raise InputError(f"unknown engine {engine!r} (use fmu or native)")
        if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 1):
            raise InputError(f"workers must be a whole number >= 1 (or None: one per seed up to the "
                             f"cores), got {workers!r}")
        self.source = source
        self.n, self.fs, self.seeds, self.engine = int(n), float(fs), list(seeds), engine
        self.restarts = None if restarts is None else np.asarray(restarts, dtype=bool)
        self.quiet = quiet
        self.workers = workers
        self.fmu_path = fmu_path_for(fmu_dir, quiet=quiet) if engine == "fmu" else None
        self.n_runs = 0

    def run(self, text: str, engine: str | None = None) -> list[np.ndarray]:
        """The card ``text`` simulated once per seed (``engine``: this simulator's unless given)."""
        engine = engine or self.engine
        self.n_runs += len(self.seeds)
        if engine == "native":
            from gyrodenoise.simulator import simulate
            return [simulate(card_at_rate(draw_unit(text, s, self.source), self.fs, self.source), self.n, seed=s,
                             restarts=self.restarts).rate_deg_s for s in self.seeds]
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool
        fmu_path = self.fmu_path
        if fmu_path is None:
            raise ValueError("engine 'fmu' needs a Simulator made with engine='fmu' (it builds the FMU)")
        card_at_rate(text, self.fs, self.source)          # check it first
        ftexts = [text_at_rate(draw_unit(text, s, self.source), self.fs) for s in self.seeds]
        workers = self.workers or min(len(self.seeds), os.cpu_count() or 1)
        rs = None if self.restarts is None else self.restarts.tolist()
        log(f"gyrodenoise: simulating {len(self.seeds)} seeds x {self.n} samples through "
            f"{fmu_path.name} ({workers} processes)", quiet=self.quiet)
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                 max_tasks_per_child=1) as ex:
            futs = [ex.submit(_fmu_worker, str(fmu_path), ft, s, self.n, self.fs, rs)
                    for ft, s in zip(ftexts, self.seeds)]
            out = []
            try:
                for i, f in enumerate(futs):
                    r = f.result()
                    if isinstance(r, str):
                        raise InputError(f"{fmu_path.name} failed on seed {self.seeds[i]}: {r}",
                                         self.source)
                    out.append(r)
                    log(f"gyrodenoise:   seed {self.seeds[i]} done", quiet=self.quiet)
            except BrokenProcessPool as exc:
                raise InputError(f"an FMU worker process died on seed {self.seeds[len(out)]} "
                                 f"({' '.join(str(exc).split())})", self.source) from None
        return out
