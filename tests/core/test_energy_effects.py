"""Energies with joint and drive effects (:func:`hexapod_pin.core.energy.model_energies`,
:func:`~hexapod_pin.core.energy.energy_totals`): the rotors' kinetic energy and the springs'
potential energy.

Independent routes: Pinocchio's ``computeKineticEnergy`` with and without
``model.armature`` (it includes it: checked on raw Pinocchio); ``1/2 v^T (M + diag(a)) v``
with ``crba`` on a copy of the tree without armature; ``1/2 K dq^2`` with ``dq`` from
``pin.difference`` written here; the gravity potential of the rigid copy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.energy import energy_totals, model_energies

DATA = Path(__file__).resolve().parents[1] / "data"
MODELS = {
    "four_bar": lambda: hp.load_robot(DATA / "four_bar" / "four_bar.urdf").model,
    "stewart": lambda: hp.load_robot(DATA / "stewart" / "stewart.urdf").model,
    "five_bar": lambda: hp.load_parallel_robot(DATA / "parallel" / "five_bar_3d"),
}


@pytest.fixture(scope="module", params=sorted(MODELS))
def clm(request):
    return MODELS[request.param]()


def test_pinocchio_kinetic_energy_includes_the_armature():
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    rng = np.random.default_rng(0)
    q = pin.randomConfiguration(model)
    v = rng.normal(size=model.nv)
    rigid = pin.computeKineticEnergy(model, data, q, v)
    arm = rng.uniform(0.1, 1.0, model.nv)
    model.armature[:] = arm
    assert pin.computeKineticEnergy(model, data, q, v) - rigid == pytest.approx(
        0.5 * np.dot(arm * v, v), rel=1e-12)


def test_energy_parts_of_rotors_and_springs_sum_to_the_totals(clm):
    rng = np.random.default_rng(4)
    tree = clm.tree_model
    arm = rng.uniform(0.1, 0.5, clm.nv)
    stiffness = rng.uniform(5.0, 50.0, clm.nv)
    ref = pin.integrate(tree, pin.neutral(tree), rng.uniform(-0.3, 0.3, clm.nv))
    model = clm.with_effects(armature=arm, stiffness=stiffness, spring_reference=ref)
    q = pin.integrate(tree, pin.neutral(tree), rng.uniform(-0.5, 0.5, clm.nv))
    v = rng.uniform(-2.0, 2.0, clm.nv)
    e = model_energies(model, q, v)
    # written here on a rigid copy of the tree
    rigid = pin.Model(tree)
    rigid.armature[:] = 0.0
    data = rigid.createData()
    mass = pin.crba(rigid, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    rotor = 0.5 * np.dot(arm * v, v)
    dq = pin.difference(rigid, ref, q)
    springs = 0.5 * np.dot(stiffness * dq, dq)
    gravity = pin.computePotentialEnergy(rigid, data, q)
    assert e.rotor_kinetic == pytest.approx(rotor, rel=1e-12)
    assert e.kinetic == pytest.approx(0.5 * v @ mass @ v + rotor, rel=1e-12)
    assert e.kinetic_per_body.sum() + e.rotor_kinetic == pytest.approx(e.kinetic, rel=1e-12)
    assert e.spring_potential == pytest.approx(springs, rel=1e-12)
    assert e.potential == pytest.approx(gravity + springs, rel=1e-12, abs=1e-12)
    assert e.potential_per_body.sum() + e.spring_potential == pytest.approx(
        e.potential, rel=1e-12, abs=1e-12)
    assert e.total == pytest.approx(e.kinetic + e.potential, rel=1e-15, abs=1e-15)
    assert energy_totals(model, q, v) == pytest.approx((e.kinetic, e.potential), rel=1e-14)
    assert rotor > 1e-2 * e.kinetic and springs > 1e-2                # both matter here
    # the rigid model has neither part
    plain = model_energies(clm, q, v)
    assert plain.rotor_kinetic == 0.0 and plain.spring_potential == 0.0
    assert plain.kinetic == pytest.approx(0.5 * v @ mass @ v, rel=1e-12)


def test_energies_default_to_no_rotor_and_no_spring_part():
    e = hp.Energies(1.0, 2.0, 3.0)
    assert e.rotor_kinetic == 0.0 and e.spring_potential == 0.0
