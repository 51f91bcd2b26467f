import numpy as np
import pytest

from tsel_data.core import geometry as g


def test_source_on_plus_y_is_azimuth_90():
    az, el, d = g.cart_to_sph([0.0, 2.0, 0.0])
    assert az == pytest.approx(90.0) and el == pytest.approx(0.0) and d == pytest.approx(2.0)


def test_source_on_minus_x_is_minus_180():
    az, _, _ = g.cart_to_sph([-1.0, 0.0, 0.0])
    assert az == pytest.approx(-180.0)
    assert g.wrap_azimuth(180.0) == pytest.approx(-180.0)
    assert g.wrap_azimuth(-180.0) == pytest.approx(-180.0)


def test_elevation_up_and_front():
    az, el, _ = g.cart_to_sph([1.0, 0.0, 1.0])
    assert az == pytest.approx(0.0) and el == pytest.approx(45.0)


def test_sph_cart_round_trip():
    rng = np.random.default_rng(0)
    az, el, d = rng.uniform(-180, 180, 50), rng.uniform(-89, 89, 50), rng.uniform(0.5, 5, 50)
    a2, e2, d2 = g.cart_to_sph(g.sph_to_cart(az, el, d))
    np.testing.assert_allclose(g.azimuth_difference(a2, az), 0, atol=1e-9)
    np.testing.assert_allclose(e2, el, atol=1e-9)
    np.testing.assert_allclose(d2, d, atol=1e-9)


def test_foa_gains_sn3d():
    w, y, z, x = g.foa_gains(90.0, 0.0)
    assert (w, y, z, x) == pytest.approx((1.0, 1.0, 0.0, 0.0), abs=1e-12)
    w, y, z, x = g.foa_gains(0.0, 90.0)
    assert (w, y, z, x) == pytest.approx((1.0, 0.0, 1.0, 0.0), abs=1e-12)
    gains = g.foa_gains(37.0, -20.0)
    assert np.sum(gains[1:] ** 2) == pytest.approx(1.0)  # SN3D: |(Y, Z, X)| = W


def test_room_to_array_with_yaw():
    centre = (3.0, 4.0, 1.2)
    # array turned to face room +y: a point further along room +y is in front (+x)
    p = g.room_to_array([3.0, 6.0, 1.2], centre, 90.0)
    np.testing.assert_allclose(p, [2.0, 0.0, 0.0], atol=1e-12)
    # and room -x is then to the array's left (+y)
    p = g.room_to_array([1.0, 4.0, 1.2], centre, 90.0)
    np.testing.assert_allclose(p, [0.0, 2.0, 0.0], atol=1e-12)
    back = g.array_to_room(p, centre, 90.0)
    np.testing.assert_allclose(back, [1.0, 4.0, 1.2], atol=1e-12)
