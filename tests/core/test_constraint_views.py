"""The stacked constraint errors read from live views (core.constraint_views) against
fresh reads of Pinocchio's placements and against ClosedLoopModel.residual."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import stress_robots

from hexapod_pin.core.constraint_views import ConstraintErrors
from hexapod_pin.errors import InputError
from hexapod_pin.loaders import robots


def _configurations(clm, rng, n=4):
    return [pin.integrate(clm.model, pin.neutral(clm.model), 0.3 * rng.normal(size=clm.nv))
            for _ in range(n)]


@pytest.mark.parametrize("name", ["cassie", "ladder_mixed", "planar_ladder_weld"])
def test_errors_follow_every_calc(name):
    """After each calc at a new configuration, the gathered errors equal the errors written
    here from Pinocchio's anchor placements: ``R_1^T (p_1 - p_2)`` for point closures,
    ``log6(oMc2^-1 oMc1)`` for welds (LOCAL rows), ``p_1 - p_2`` in world rows."""
    clm = robots.cassie() if name == "cassie" else stress_robots.build(name).clm
    model = clm.model
    data = model.createData()
    cms, cds = clm.pinocchio_constraints()
    errors = ConstraintErrors(model, cms, cds, "local")
    all_points = all(cm.type == pin.ContactType.CONTACT_3D for cm in cms)
    assert errors.live == all_points
    world = None
    if all_points:
        wms, wds = clm.pinocchio_constraints()
        world = ConstraintErrors(model, wms, wds, "world")
        assert world.live
    out = np.empty(clm.n_rows)
    for q in _configurations(clm, np.random.default_rng(4)):
        pin.forwardKinematics(model, data, q)
        for cm, cd in zip(cms, cds):
            cm.calc(model, data, cd)
        expected = []
        for cm, cd in zip(cms, cds):
            m1, m2 = cd.oMc1, cd.oMc2
            if cm.type == pin.ContactType.CONTACT_3D:
                expected.append(m1.rotation.T @ (m1.translation - m2.translation))
            else:
                expected.append(pin.log6(m2.actInv(m1)).vector)
        got = errors.gather(out)
        assert got is out
        assert np.max(np.abs(np.concatenate(expected))) > 1e-3      # off the closures
        np.testing.assert_allclose(got, np.concatenate(expected), rtol=0, atol=1e-12)
        if world is not None:
            for cm, cd in zip(wms, wds):
                cm.calc(model, data, cd)
            # world rows p_1 - p_2: fresh reads of the anchors (LOCAL and world rows have
            # the same norm per closure)
            want = np.concatenate([cd.oMc1.translation - cd.oMc2.translation for cd in wds])
            got_world = world.gather(np.empty(clm.n_rows))
            np.testing.assert_allclose(got_world, want, rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.linalg.norm(got_world.reshape(-1, 3), axis=1),
                                       np.linalg.norm(got.reshape(-1, 3), axis=1),
                                       rtol=0, atol=1e-12)


def test_errors_without_live_views_read_the_properties(monkeypatch):
    """Where the bindings would return copies, the check at construction finds it and the
    errors are read through the properties (same values)."""
    clm = robots.cassie()
    model, data = clm.model, clm.model.createData()
    cms, cds = clm.pinocchio_constraints()
    monkeypatch.setattr(ConstraintErrors, "_gather_views",
                        lambda self, views, out: out * np.nan)     # stale / wrong views
    errors = ConstraintErrors(model, cms, cds, "local")
    assert not errors.live
    q = _configurations(clm, np.random.default_rng(1), 1)[0]
    pin.forwardKinematics(model, data, q)
    for cm, cd in zip(cms, cds):
        cm.calc(model, data, cd)
    expected = np.concatenate([-cd.c1Mc2.translation for cd in cds])
    np.testing.assert_array_equal(errors.gather(np.empty(clm.n_rows)), expected)


def test_bad_rows_are_refused():
    clm = stress_robots.build("planar_ladder_weld").clm
    cms, cds = clm.pinocchio_constraints()
    with pytest.raises(InputError, match="rows"):
        ConstraintErrors(clm.model, cms, cds, "body")
    with pytest.raises(InputError, match="point closures only"):
        ConstraintErrors(clm.model, cms, cds, "world")


def test_gather_kernels_match_numpy():
    """The compiled gathers against numpy: ``-concatenate(views)`` and
    ``concatenate(first) - concatenate(second)``, for tuples of one and of several
    arrays."""
    from hexapod_pin.core.constraint_views import gather_difference, gather_negated

    rng = np.random.default_rng(0)
    for n in (1, 4, 7):
        first = tuple(rng.normal(size=3) for _ in range(n))
        second = tuple(rng.normal(size=3) for _ in range(n))
        out = np.empty(3 * n)
        gather_negated(first, out)
        np.testing.assert_array_equal(out, -np.concatenate(first))
        gather_difference(first, second, out)
        np.testing.assert_array_equal(out, np.concatenate(first) - np.concatenate(second))
