"""ENU <-> WGS84 around the mission origin (pymap3d), the only geodesy in sitl."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymap3d


class LocalFrame:
    """A local east-north-up frame (metres) whose origin is a WGS84 point (degrees, metres AMSL)."""

    def __init__(self, lat: float, lon: float, alt: float) -> None:
        self.lat0, self.lon0, self.alt0 = float(lat), float(lon), float(alt)

    def to_geodetic(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        lat, lon, alt = pymap3d.enu2geodetic(x, y, z, self.lat0, self.lon0, self.alt0)
        return float(lat), float(lon), float(alt)

    def to_geodetic_many(self, xyz: Sequence[Sequence[float]]) -> list[tuple[float, float, float]]:
        """Convert many points in one vectorised call (much cheaper than one call per point)."""
        if not xyz:
            return []
        arr = np.asarray(xyz, dtype=float)
        lat, lon, alt = pymap3d.enu2geodetic(arr[:, 0], arr[:, 1], arr[:, 2], self.lat0, self.lon0, self.alt0)
        return list(zip(np.atleast_1d(lat).tolist(), np.atleast_1d(lon).tolist(),
                        np.atleast_1d(alt).tolist(), strict=True))

    def to_enu(self, lat: float, lon: float, alt: float) -> tuple[float, float, float]:
        x, y, z = pymap3d.geodetic2enu(lat, lon, alt, self.lat0, self.lon0, self.alt0)
        return float(x), float(y), float(z)
