"""See-through balls for the "mesh" image kind: a thin spherical shell of which only a pattern
is solid, so the background shows through it (issue 11: "a sphere of any surface (open mesh ...)").

:class:`OpenShell` is a :class:`~calib_core.synth.primitives.MeshSphere` (the same ray march
through the layer between ``radius_m - wire_m`` and ``radius_m``, see
:mod:`calib_core.synth.scene`) whose solid part is one of:

- "lattice": latitude and longitude struts (``n_lat`` bands, ``n_lon`` meridians), as the
  product's own mesh target; few and thick struts make a cage float;
- "net": a knotted diamond net: two families of loxodromes (curves crossing every meridian
  at the same angle, so the cells keep their diamond shape from the equator to the poles):
  with the Mercator latitude m = ln tan(theta / 2), the lines ``phi + k m = 2 pi j / n_lon``
  and ``phi - k m = 2 pi j / n_lon``; a strand's angular half width is the given half width
  measured across the strand (the phi distance times sin(theta) / sqrt(1 + k^2)), and a knot
  (a disc of 1.8x the strand's half width) sits at every crossing;
- "holes": a wiffle-type ball: a solid shell with ``n_holes`` round holes centred on a
  Fibonacci sphere (even spacing), each of angular radius ``hole_deg``.

Seen edge-on at the limb the struts pile up, so the outline is a chain of short strut
segments at the outer radius; inside it the background (and the back half of the shell)
shows. Normals are radial (as for MeshSphere). The key light's cast shadow of such a ball is
not modelled (the renderer's shadow is a solid disc), so the scenes draw none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.synth.primitives import MeshSphere, frame_from_normal

PATTERNS = ("lattice", "net", "holes")


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n,3) unit vectors spread evenly over the sphere."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    s = np.sqrt(1 - z * z)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


@dataclass(frozen=True)
class OpenShell(MeshSphere):
    """A shell with only ``pattern`` solid (see the module doc); ``twist`` is the net's k,
    ``n_holes`` / ``hole_deg`` the wiffle ball's holes."""

    pattern: str = "lattice"
    twist: float = 1.0
    n_holes: int = 12
    hole_deg: float = 20.0

    def _on_wire(self, p):
        if self.pattern == "lattice":
            return MeshSphere._on_wire(self, p)
        q = p @ frame_from_normal(self.pole)
        rho = np.maximum(np.linalg.norm(q, axis=1), 1e-12)
        if self.pattern == "holes":
            near = (q / rho[:, None]) @ fibonacci_sphere(self.n_holes).T
            return near.max(axis=1) < np.cos(np.deg2rad(self.hole_deg))
        return self._on_net(q, rho)

    def _on_net(self, q, rho):
        theta = np.clip(np.arccos(np.clip(q[:, 2] / rho, -1, 1)), 1e-4, np.pi - 1e-4)
        phi = np.arctan2(q[:, 1], q[:, 0])
        m = np.log(np.tan(theta / 2))
        half = 0.5 * self.wire_m / self.radius_m
        step = 2 * np.pi / self.n_lon
        across = np.sin(theta) / np.sqrt(1 + self.twist ** 2)
        on = np.zeros(len(q), bool)
        gaps = []
        for sgn in (1.0, -1.0):
            a = phi + sgn * self.twist * m
            gap = np.abs(a - np.round(a / step) * step) * across
            gaps.append(gap)
            on |= gap < half
        knot = np.hypot(gaps[0], gaps[1]) < 1.8 * half
        return on | knot | (theta < 2 * half) | (theta > np.pi - 2 * half)
