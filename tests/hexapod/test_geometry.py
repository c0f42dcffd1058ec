import math

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin.errors import GeometryError


def test_defaults_and_home_height():
    g = hp.HexapodGeometry()
    # home height from the leg-length triangle, computed by hand
    assert g.home_height == pytest.approx(math.sqrt(0.45**2 - 0.23**2 - 0.15**2), abs=1e-15)
    assert g.home_height == pytest.approx(0.3565, abs=1e-4)
    np.testing.assert_array_equal(g.home_q, [-0.15, 0.15, -0.15, 0.15, -0.15, 0.15])


def test_rail_frames_follow_the_convention():
    g = hp.HexapodGeometry()
    for k in range(3):
        a = math.radians(90 + 120 * k)
        np.testing.assert_allclose(g.rail_midpoints[k], [0.35 * math.cos(a), 0.35 * math.sin(a), 0],
                                   atol=1e-15)
        np.testing.assert_allclose(g.rail_directions[k], [-math.sin(a), math.cos(a), 0], atol=1e-15)
        np.testing.assert_allclose(g.platform_points[k], [0.12 * math.cos(a), 0.12 * math.sin(a), 0],
                                   atol=1e-15)


@pytest.mark.parametrize("field,value", [
    ("rail_radius", 0.0), ("platform_radius", -0.1), ("leg_length", -1.0), ("carriage_mass", 0.0),
    ("leg_mass", -0.3), ("platform_mass", 0.0), ("gravity", -9.81), ("max_actuator_force", 0.0),
    ("rail_radius", float("nan")), ("leg_length", float("inf")), ("rail_radius", "a"),
    ("carriage_min_gap", -0.01),
])
def test_invalid_scalars_raise(field, value):
    with pytest.raises(GeometryError) as info:
        hp.HexapodGeometry(**{field: value})
    assert info.value.field == field


@pytest.mark.parametrize("inertia", [(0.004, 0.004, 0.0), (0.004, -0.004, 0.008),
                                     (0.001, 0.001, 0.01), (0.004, 0.004), ("a", 1, 2)])
def test_invalid_inertia_raises(inertia):
    with pytest.raises(GeometryError) as info:
        hp.HexapodGeometry(platform_inertia=inertia)
    assert info.value.field == "platform_inertia"


def test_home_that_cannot_assemble_raises():
    with pytest.raises(GeometryError, match="cannot be assembled"):
        hp.HexapodGeometry(leg_length=0.25)
    with pytest.raises(GeometryError, match="stroke"):
        hp.HexapodGeometry(carriage_home=0.35)
    with pytest.raises(GeometryError, match="carriage_min_gap"):
        hp.HexapodGeometry(carriage_home=0.005)


def test_frozen_and_replace():
    g = hp.HexapodGeometry()
    with pytest.raises(Exception):
        g.leg_length = 1.0
    g2 = g.replace(leg_length=0.5)
    assert g2.leg_length == 0.5 and g.leg_length == 0.45
    with pytest.raises(GeometryError):
        g.replace(leg_length=-2)
