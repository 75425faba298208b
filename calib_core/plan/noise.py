"""Detection noise of a capture not taken yet, fitted to the captures already taken.

Image centre: the median of the existing pixel covariances (px^2). Sonar centre: along the
sonar ray a constant sigma (range resolution), across it a sigma growing with range (the beam
footprint); both are medians over the existing captures' stated covariances. With no captures
the defaults below are used (the synthetic benchmark's noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NoiseModel:
    """cov_uv_px2 (2,2); sonar sigma along the ray (m) and across it per metre of range (m/m)."""

    cov_uv_px2: np.ndarray
    sigma_along_m: float
    sigma_across_per_m: float

    def sonar_cov(self, X_sonar_m: np.ndarray) -> np.ndarray:
        """(N,3,3) predicted sonar-centre covariances at sonar-frame centres."""
        X = np.asarray(X_sonar_m, float).reshape(-1, 3)
        r = np.maximum(np.linalg.norm(X, axis=1), 1e-6)
        u = X / r[:, None]
        P = u[:, :, None] * u[:, None, :]
        across = (self.sigma_across_per_m * r) ** 2
        return self.sigma_along_m**2 * P + across[:, None, None] * (np.eye(3)[None] - P)


def default_noise() -> NoiseModel:
    return NoiseModel(np.eye(2) * 0.5**2, 0.003, 0.003)


def fit_noise(cov_uv_px2: np.ndarray, X_sonar_m: np.ndarray, cov_X_m2: np.ndarray) -> NoiseModel:
    """Medians of the existing captures' stated covariances (see the module doc)."""
    cuv = np.asarray(cov_uv_px2, float).reshape(-1, 2, 2)
    X = np.asarray(X_sonar_m, float).reshape(-1, 3)
    cX = np.asarray(cov_X_m2, float).reshape(-1, 3, 3)
    if len(cuv) == 0 or len(X) == 0:
        return default_noise()
    r = np.maximum(np.linalg.norm(X, axis=1), 1e-6)
    u = X / r[:, None]
    along = np.einsum("ni,nij,nj->n", u, cX, u)
    across = np.maximum((np.trace(cX, axis1=1, axis2=2) - along) / 2.0, 0.0)
    return NoiseModel(np.median(cuv, axis=0), float(np.sqrt(np.median(np.maximum(along, 0)))),
                      float(np.median(np.sqrt(across) / r)))
