"""WGS84 Earth model: constants, radii of curvature, normal gravity, Earth and transport rate.

Everything here is for the NED local-level frame at geodetic latitude ``lat`` (rad) and
ellipsoidal height ``h`` (m).

- Radii of curvature: meridian R_N = a(1-e^2)/(1-e^2 sin^2 lat)^1.5 and transverse
  (prime vertical) R_E = a/sqrt(1-e^2 sin^2 lat) (Groves 2013, eqs. 2.105-2.106).
- Normal gravity on the ellipsoid by Somigliana's formula, with the second-order height
  correction of Groves (2013) eq. 2.134 / NIMA TR8350.2: the down component
  g(lat, h) = g0(lat) [1 - 2/a (1 + f + m - 2 f sin^2 lat) h + 3 h^2 / a^2].
  Gravity here is *gravity* (gravitation plus centrifugal), as a strapdown NED
  mechanization needs (Groves 2013 sec. 5.4); the small north component is neglected.
- Earth rate in NED: Omega [cos lat, 0, -sin lat]; transport rate:
  [v_E/(R_E+h), -v_N/(R_N+h), -v_E tan(lat)/(R_E+h)] (Groves 2013 eq. 5.44).

Reference: NIMA TR8350.2 (WGS84), Groves (2013) ch. 2 and 5.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

A = 6378137.0  #: semi-major axis (m)
F = 1.0 / 298.257223563  #: flattening
B = A * (1.0 - F)  #: semi-minor axis (m)
E2 = F * (2.0 - F)  #: first eccentricity squared
OMEGA_IE = 7.292115e-5  #: Earth rotation rate (rad/s)
GM = 3.986004418e14  #: gravitational constant (m^3/s^2)
GAMMA_E = 9.7803253359  #: normal gravity at the equator (m/s^2)
GAMMA_P = 9.8321849378  #: normal gravity at the poles (m/s^2)
SOMIGLIANA_K = (B * GAMMA_P - A * GAMMA_E) / (A * GAMMA_E)
M_RATIO = OMEGA_IE**2 * A**2 * B / GM  #: m = w^2 a^2 b / GM


@njit(cache=True)
def radii(lat):
    """(R_N meridian, R_E transverse) radii of curvature (m) at geodetic latitude lat."""
    s2 = math.sin(lat) ** 2
    d = 1.0 - E2 * s2
    re = A / math.sqrt(d)
    rn = re * (1.0 - E2) / d
    return rn, re


@njit(cache=True)
def gravity(lat, h):
    """Magnitude (down component) of normal gravity (m/s^2) at latitude lat, height h."""
    s2 = math.sin(lat) ** 2
    g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / math.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))


@njit(cache=True)
def earth_rate_ned(lat):
    """Earth rotation rate vector resolved in NED (rad/s)."""
    return np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])


@njit(cache=True)
def transport_rate_ned(lat, h, v_ned):
    """Transport rate (rotation of NED relative to the Earth) resolved in NED (rad/s)."""
    rn, re = radii(lat)
    return np.array([
        v_ned[1] / (re + h),
        -v_ned[0] / (rn + h),
        -v_ned[1] * math.tan(lat) / (re + h),
    ])


def radii_array(lat):
    """Vectorised radii(lat) -> (R_N, R_E) arrays."""
    s2 = np.sin(np.asarray(lat, float)) ** 2
    d = 1.0 - E2 * s2
    re = A / np.sqrt(d)
    return re * (1.0 - E2) / d, re


def gravity_array(lat, h):
    """Vectorised gravity(lat, h)."""
    s2 = np.sin(np.asarray(lat, float)) ** 2
    h = np.asarray(h, float)
    g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / np.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))


class LocalTangent:
    """Small-area map between geodetic coordinates and local north/east/down metres.

    North = (lat - lat0)(R_N(lat0) + h0), east = (lon - lon0)(R_E(lat0) + h0) cos(lat0),
    down = h0 - h. Over the 30 km extent of a DEM tile the scale error of this
    equirectangular map is below 1e-5 (the radii change by that fraction), i.e. well under a
    DEM post; it is used to express TRN fixes and errors in metres, never to integrate.
    """

    def __init__(self, lat0: float, lon0: float, h0: float = 0.0):
        from navgate.nav import validate

        # at a pole the east scale (R_E + h0) cos(lat0) is 0 and to_geodetic divides by it
        self.lat0 = validate.nav_latitude("lat0", lat0)
        self.lon0 = validate.finite_scalar("lon0", lon0)
        self.h0 = validate.height_m("h0", h0)
        rn, re = radii(self.lat0)
        self.m_per_rad_lat = rn + self.h0
        self.m_per_rad_lon = (re + self.h0) * math.cos(self.lat0)

    def to_ned(self, lat, lon, h=None):
        """Geodetic (rad, rad, m) -> (north, east[, down]) metres."""
        north = (np.asarray(lat, float) - self.lat0) * self.m_per_rad_lat
        east = (np.asarray(lon, float) - self.lon0) * self.m_per_rad_lon
        if h is None:
            return north, east
        return north, east, self.h0 - np.asarray(h, float)

    def to_geodetic(self, north, east):
        """(north, east) metres -> (lat, lon) rad."""
        lat = self.lat0 + np.asarray(north, float) / self.m_per_rad_lat
        lon = self.lon0 + np.asarray(east, float) / self.m_per_rad_lon
        return lat, lon
