"""One identified parameter with its 95 % confidence interval: what every fit returns (the
Allan fit, GMWM, the output stage's line amplitudes), so the results speak one language."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Estimate:
    """One identified parameter with its 95 % confidence interval (finite, ordered)."""

    value: float
    ci_low: float
    ci_high: float
    unit: str

    def as_dict(self, scale: float = 1.0, unit: str | None = None) -> dict[str, Any]:
        return {
            "value": json_float(self.value * scale),
            "ci95": [json_float(self.ci_low * scale), json_float(self.ci_high * scale)],
            "unit": unit or self.unit,
        }


def json_float(value: float) -> float | None:
    """A float for strict JSON: None for NaN and infinities."""
    return float(value) if math.isfinite(value) else None
