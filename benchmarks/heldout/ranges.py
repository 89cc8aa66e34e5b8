"""A published range a parameter is drawn from (uniform, or uniform in its logarithm)."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Range:
    lo: float
    hi: float
    log: bool = False

    def draw(self, rng: np.random.Generator) -> float:
        if self.lo == self.hi:
            return float(self.lo)
        if self.log:
            return float(np.exp(rng.uniform(np.log(self.lo), np.log(self.hi))))
        return float(rng.uniform(self.lo, self.hi))

    def draw_signed(self, rng: np.random.Generator) -> float:
        """A magnitude from the range with a random sign."""
        return self.draw(rng) * (1.0 if rng.random() < 0.5 else -1.0)

    def contains(self, value: float) -> bool:
        return self.lo <= value <= self.hi

    def __str__(self) -> str:
        return f"{self.lo:g}..{self.hi:g}" + (" (log)" if self.log else "")
