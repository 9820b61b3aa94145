"""WGS84 Earth model against known values and exact identities (docs/guide/theory.rst, 'Navigation filter')."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.nav import earth


def test_constants_and_radii_known_values():
    rm, rn = earth.radii(0.0)
    assert rn == pytest.approx(6378137.0, abs=1e-6)
    assert rm == pytest.approx(6335439.327, abs=1e-3)  # a(1−e²)
    rm_p, rn_p = earth.radii(math.pi / 2)
    assert rm_p == pytest.approx(rn_p, rel=1e-12)  # both equal a²/b at the pole
    assert rn_p == pytest.approx(6399593.626, abs=1e-3)
    assert earth.E2 == pytest.approx(6.69437999014e-3, rel=1e-10)


def test_normal_gravity_somigliana():
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803267715, abs=1e-10)
    # the KF-GINS series form is 0.12 mGal below the closed Somigliana value at the pole
    assert earth.gravity(math.pi / 2, 0.0) == pytest.approx(9.8321863685, abs=2e-6)
    # free-air gradient ≈ −3.086e-6 s⁻² per m at 45°
    g0, g1 = earth.gravity(math.radians(45), 0.0), earth.gravity(math.radians(45), 1000.0)
    assert (g1 - g0) / 1000.0 == pytest.approx(-3.086e-6, rel=2e-3)
    # vectorised form agrees with the scalar one
    lat = np.radians([0.0, 30.0, 60.0])
    np.testing.assert_allclose(earth.gravity(lat, 100.0), [earth.gravity(x, 100.0) for x in lat])


def test_ecef_known_points_and_roundtrip():
    np.testing.assert_allclose(earth.llh_to_ecef(np.array([0.0, 0.0, 0.0])), [earth.A, 0, 0], atol=1e-9)
    b = earth.A * (1 - earth.F)
    np.testing.assert_allclose(earth.llh_to_ecef(np.array([math.pi / 2, 0.3, 0.0])), [0, 0, b], atol=1e-6)
    rng = np.random.default_rng(0)
    llh = np.column_stack(
        [rng.uniform(-1.55, 1.55, 500), rng.uniform(-math.pi, math.pi, 500), rng.uniform(-500, 2e4, 500)]
    )
    back = earth.ecef_to_llh(earth.llh_to_ecef(llh))
    np.testing.assert_allclose(back[:, :2], llh[:, :2], atol=1e-12)
    np.testing.assert_allclose(back[:, 2], llh[:, 2], atol=1e-6)


def test_ned_offsets_exact_and_inverse():
    llh0 = np.array([math.radians(40.0966), math.radians(-105.147), 1600.0])
    ned = np.array([[100.0, -250.0, 3.0], [0.0, 0.0, -10.0], [5000.0, 5000.0, 0.0]])
    np.testing.assert_allclose(earth.llh_to_ned(earth.ned_to_llh(ned, llh0), llh0), ned, atol=1e-6)
    # a pure height change is a pure −D offset; a small northing matches the meridian radius
    up = llh0 + [0, 0, 10.0]
    np.testing.assert_allclose(earth.llh_to_ned(up[None], llh0)[0], [0, 0, -10.0], atol=1e-9)
    rm, _ = earth.radii(llh0[0])
    north = llh0 + [1e-6, 0, 0]
    assert earth.llh_to_ned(north[None], llh0)[0, 0] == pytest.approx(1e-6 * (rm + llh0[2]), rel=1e-6)


def test_euler_dcm_roundtrip_and_orthogonality():
    rng = np.random.default_rng(1)
    for _ in range(50):
        e = np.array([rng.uniform(-3, 3), rng.uniform(-1.5, 1.5), rng.uniform(-3, 3)])
        C = earth.euler_to_dcm(*e)
        np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(C) == pytest.approx(1.0)
        np.testing.assert_allclose(earth.dcm_to_euler(C), e, atol=1e-12)
    # yaw 90°: body x points east
    np.testing.assert_allclose(earth.euler_to_dcm(0, 0, math.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_earth_and_transport_rate():
    lat = math.radians(40.0)
    w = earth.omega_ie_n(lat)
    assert np.linalg.norm(w) == pytest.approx(earth.OMEGA_E)
    assert w[2] < 0  # NED: the Earth rate points up in the northern hemisphere
    rm, rn = earth.radii(lat)
    v = np.array([10.0, 20.0, 0.0])
    wen = earth.omega_en_n(lat, 100.0, v)
    np.testing.assert_allclose(wen, [20 / (rn + 100), -10 / (rm + 100), -20 * math.tan(lat) / (rn + 100)])
    C = earth.ecef_to_ned_matrix(lat, 0.2)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-15)
    # Earth rate in ECEF is [0, 0, Ω]
    np.testing.assert_allclose(C @ [0, 0, earth.OMEGA_E], w, atol=1e-18)
