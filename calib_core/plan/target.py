"""The operator's target precision (1-sigma per axis) and whether a covariance meets it."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from calib_core.plan.information import sigmas_deg_mm

_PART = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:e-?[0-9]+)?)\s*(deg|mm|m|cm|rad)\s*$", re.I)


@dataclass(frozen=True)
class Target:
    """Wanted 1-sigma per axis: rotation (deg, about each camera axis) and translation (mm)."""

    rotation_deg: float = 0.1
    translation_mm: float = 5.0

    def text(self) -> str:
        return f"{self.rotation_deg:g} deg / {self.translation_mm:g} mm (1-sigma per axis)"

    def ratio(self, cov6: np.ndarray) -> np.ndarray:
        """(...,) worst axis sigma / target over rotation and translation (<= 1: met)."""
        r, t = sigmas_deg_mm(cov6)
        return np.maximum(r.max(axis=-1) / self.rotation_deg, t.max(axis=-1) / self.translation_mm)

    def met(self, cov6: np.ndarray) -> bool:
        return bool(np.all(self.ratio(cov6) <= 1.0))


def parse_target(text: str) -> Target:
    """``"0.1deg,5mm"`` (either order; deg or rad, mm, cm or m) -> Target; ValueError with the reason."""
    parts = [p for p in str(text).replace("/", ",").split(",") if p.strip()]
    rot = trans = None
    for p in parts:
        m = _PART.match(p)
        if not m:
            raise ValueError(f"cannot read {p.strip()!r}: give e.g. 0.1deg,5mm")
        v, unit = float(m.group(1)), m.group(2).lower()
        if v <= 0:
            raise ValueError(f"{p.strip()!r}: the target must be positive")
        if unit in ("deg", "rad"):
            rot = v if unit == "deg" else float(np.degrees(v))
        else:
            trans = v * {"mm": 1.0, "cm": 10.0, "m": 1000.0}[unit]
    if rot is None or trans is None:
        raise ValueError("give both a rotation and a translation target, e.g. 0.1deg,5mm")
    return Target(rot, trans)
