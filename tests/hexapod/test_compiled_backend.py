"""``hp.simulate(hexapod, ..., backend="compiled")``: the compiled platform-coordinate
simulator behind the generic API, against the Pinocchio tree backend (two independent
integrations of the same mechanism) and the energy balance."""

from __future__ import annotations

import numpy as np
import pytest

import hexapod_pin as hp


@pytest.fixture(scope="module")
def hexapod():
    return hp.Hexapod.default()


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_compiled_equals_tree_backend(hexapod, integrator):
    forces = np.array([5.0, -3.0, 4.0, 2.0, -1.0, 6.0])
    tree = hp.simulate(hexapod, 0.15, 1e-3, actuator_forces=forces, integrator=integrator)
    fast = hp.simulate(hexapod, 0.15, 1e-3, actuator_forces=forces, integrator=integrator,
                       backend="compiled")
    assert type(fast) is type(tree) and fast.status == tree.status == "completed"
    # RK4: both fourth order (1e-10 m apart); Euler: first order in different coordinates
    tol = 1e-9 if integrator == "rk4" else 2e-3
    np.testing.assert_allclose(fast.times, tree.times, atol=1e-15)
    np.testing.assert_allclose(fast.poses, tree.poses, atol=tol)
    np.testing.assert_allclose(fast.actuator_positions, tree.actuator_positions, atol=tol)
    assert fast.closure_residual.max() < 1e-12
    np.testing.assert_allclose(fast.twists, tree.twists, rtol=0 if integrator == "rk4" else 2e-2,
                               atol=10 * tol)
    if integrator == "rk4":
        balance = fast.energies - fast.energies[0] - fast.work
        assert np.abs(balance).max() < 1e-7 * max(1.0, np.abs(fast.work).max())


def test_compiled_backend_refuses_what_it_does_not_do(hexapod):
    hold = (hexapod.home_pose, np.zeros(6), np.zeros(6))
    for kwargs in ({"controller": hp.ComputedTorque(lambda t: hold, 100.0, 20.0)},
                   {"actuator_forces": lambda t: np.zeros(6)},
                   {"initial": (hexapod.home_configuration, np.zeros(hexapod.model.nv))},
                   {"method": "kkt"}):
        with pytest.raises(hp.InputError) as err:
            hp.simulate(hexapod, 0.01, 1e-3, backend="compiled", **kwargs)
        assert err.value.name == "backend"
    with pytest.raises(hp.InputError, match="no compiled simulator"):
        hp.simulate(hp.Planar3PRR.default(), 0.01, 1e-3, backend="compiled")
    with pytest.raises(hp.InputError):
        hp.simulate(hexapod, 0.01, 1e-3, backend="gpu")


def test_compiled_sampling_work_and_duration_match_the_tree_backend(hexapod):
    forces = np.array([5.0, -3.0, 4.0, 2.0, -1.0, 6.0])
    for every in (1, 3, 20):
        tree = hp.simulate(hexapod, 0.05, 1e-3, actuator_forces=forces, record_every=every)
        fast = hp.simulate(hexapod, 0.05, 1e-3, actuator_forces=forces, record_every=every,
                           backend="compiled")
        np.testing.assert_allclose(fast.times, tree.times, atol=1e-15)   # the end included
        np.testing.assert_allclose(fast.work, tree.work, atol=1e-9)
        np.testing.assert_allclose(fast.energies, tree.energies, atol=1e-8)
    with pytest.raises(hp.InputError) as err:
        hp.simulate(hexapod, 1e-4, 1e-3, backend="compiled")
    assert err.value.name == "duration"
    with pytest.raises(hp.InputError):
        hp.simulate(hexapod, 0.01, 1e-3, backend=np.array(["compiled"]))
