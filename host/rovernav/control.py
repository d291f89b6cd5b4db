"""The rover's moving-to-a-pose gains and the rule that says which are stable.

Both the configuration's checks (rovernav.config: a rover must not be sent gains that break
the rule) and the study (rovernav.study.pose, which simulates the law) use `PoseGains`; it
lives here, below both, so the configuration need not import the study.

Stability (Siegwart & Nourbakhsh, the law's source): locally exponentially stable when
Kρ > 0, Kβ < 0 and Kα − Kρ > 0; `PoseGains` refuses gains that break one of these. The strong
condition Kα + 5/3·Kβ − 2/π·Kρ > 0 (α never leaves (−π/2, π/2], so the rover never reverses)
is checked only on request (`check(strong=True)`) and reported as `strongly_stable`.
"""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass(frozen=True)
class PoseGains:
    """The law's three proportional gains: v = Kρ·ρ [m/s], ω = Kα·α + Kβ·β [rad/s]."""

    k_rho: float = 0.100  # the seed report's Table 1 (rovernav.study)
    k_alpha: float = 0.145
    k_beta: float = -0.190

    def __post_init__(self) -> None:
        for name in ("k_rho", "k_alpha", "k_beta"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"pose gains: {name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        self.check()

    @property
    def strong_margin(self) -> float:
        """Kα + 5/3·Kβ − 2/π·Kρ: positive when the strong stability condition holds."""
        return self.k_alpha + 5.0 / 3.0 * self.k_beta - 2.0 / math.pi * self.k_rho

    @property
    def strongly_stable(self) -> bool:
        return self.strong_margin > 0

    def check(self, strong: bool = False) -> None:
        """Raise ValueError naming the first stability condition the gains break."""
        if not self.k_rho > 0:
            raise ValueError(f"unstable gains: K_rho > 0 required, got K_rho = {self.k_rho:g}")
        if not self.k_beta < 0:
            raise ValueError(f"unstable gains: K_beta < 0 required, got K_beta = {self.k_beta:g}")
        if not self.k_alpha - self.k_rho > 0:
            raise ValueError(
                f"unstable gains: K_alpha - K_rho > 0 required, got "
                f"{self.k_alpha:g} - {self.k_rho:g} = {self.k_alpha - self.k_rho:g}"
            )
        if strong and not self.strongly_stable:
            raise ValueError(
                f"gains not strongly stable: K_alpha + 5/3 K_beta - 2/pi K_rho > 0 required, got {self.strong_margin:g}"
            )
