"""WGS84 model against published values (NIMA TR8350.2)."""

import math

import numpy as np

from navgate.nav import earth


def test_normal_gravity_published_values():
    # Somigliana: equator and pole values are the WGS84 defining gamma_e, gamma_p
    assert math.isclose(earth.gravity(0.0, 0.0), 9.7803253359, abs_tol=1e-10)
    assert math.isclose(earth.gravity(math.pi / 2, 0.0), 9.8321849378, abs_tol=1e-9)
    # 45 deg: 9.806199 m/s^2 (TR8350.2 table 4.1 style value)
    assert math.isclose(earth.gravity(math.radians(45), 0.0), 9.8061977, abs_tol=2e-6)


def test_gravity_decreases_with_height_at_free_air_gradient():
    # free-air gradient about -3.086e-6 s^-2 near the surface
    g0 = earth.gravity(math.radians(40), 0.0)
    g1 = earth.gravity(math.radians(40), 1000.0)
    assert math.isclose((g1 - g0) / 1000.0, -3.086e-6, rel_tol=0.01)


def test_radii_of_curvature():
    rn, re = earth.radii(0.0)
    assert math.isclose(re, earth.A)
    assert math.isclose(rn, earth.A * (1 - earth.E2), rel_tol=1e-15)
    rn, re = earth.radii(math.pi / 2)
    assert math.isclose(rn, re, rel_tol=1e-15)  # at the pole both equal a^2/b
    assert math.isclose(re, earth.A**2 / earth.B, rel_tol=1e-12)


def test_earth_and_transport_rate():
    lat = math.radians(36.6)
    w = earth.earth_rate_ned(lat)
    assert math.isclose(np.linalg.norm(w), earth.OMEGA_IE)
    assert math.isclose(math.degrees(earth.OMEGA_IE) * 3600, 15.041, abs_tol=1e-3)
    # flying east at 100 m/s: transport rate about north is v/(R_E + h)
    rn, re = earth.radii(lat)
    t = earth.transport_rate_ned(lat, 500.0, np.array([0.0, 100.0, 0.0]))
    assert math.isclose(t[0], 100.0 / (re + 500.0))
    assert t[1] == 0.0
    assert math.isclose(t[2], -100.0 * math.tan(lat) / (re + 500.0))


def test_local_tangent_round_trip():
    tan = earth.LocalTangent(math.radians(36.6), math.radians(-84.2), 300.0)
    n, e = tan.to_ned(math.radians(36.7), math.radians(-84.1))
    lat, lon = tan.to_geodetic(n, e)
    assert math.isclose(lat, math.radians(36.7), abs_tol=1e-15)
    assert math.isclose(lon, math.radians(-84.1), abs_tol=1e-15)
    assert 11000 < n < 11200 and 8800 < e < 9000  # 0.1 deg in latitude ~ 11.1 km
