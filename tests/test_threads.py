"""One robot object used from several threads gives, bit for bit, the serial answers.

The robots' calls take turns on the robot's lock (their components share scratch arrays,
Pinocchio data and ProxSuite problems); the lazy parts of results (closure forces, joint
wrenches, residuals) take the same lock; the generic tree routes keep one workspace per
thread. The threads switch every microsecond here, so an unguarded shared buffer shows.
"""

import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_pose

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.errors import AssemblyError
from hexapod_pin.hexapod.fast import fast_dynamics
from hexapod_pin.loaders import robots

N_STATES = 24


@pytest.fixture
def fast_switching():
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    yield
    sys.setswitchinterval(old)


def _states(robot, rng):
    dim = robot.pose_dim
    out = []
    for _ in range(N_STATES):
        if dim == 6:
            pose = random_pose(robot, rng)
        else:
            pose = robot.home_pose + rng.uniform(-0.02, 0.02, 3) * [1, 1, 3]
        out.append((pose, 0.2 * rng.normal(size=dim), rng.normal(size=dim),
                    rng.normal(size=dim)))
    return out


def _calls(robot):
    """Functions of one state whose results must not depend on other threads."""
    def inverse(s, method):
        res = robot.inverse_dynamics(*s, method=method, bounded=False)
        return np.concatenate([res.actuator_forces, res.closure_forces.ravel(),
                               [res.residual], res.multipliers])

    def forward(s, method):
        tau = robot.inverse_dynamics(*s, bounded=False).actuator_forces
        res = robot.forward_dynamics(s[0], s[1], tau, s[3], method=method)
        return np.concatenate([res.twist_dot, res.closure_forces.ravel()])

    def wrenches(s):
        table = robot.inverse_dynamics(*s, bounded=False).joint_wrenches
        return np.concatenate([table[name] for name in sorted(table)])

    return {
        "inverse kkt": lambda s: inverse(s, "kkt"),
        "inverse qp": lambda s: inverse(s, "qp"),
        "forward nullspace": lambda s: forward(s, "nullspace"),
        "forward kkt": lambda s: forward(s, "kkt"),
        "joint wrenches": wrenches,
        "statics": lambda s: robot.static_forces(s[0], s[3], bounded=False),
        "reduced": lambda s: np.concatenate([m.ravel() for m in robot.reduced_dynamics(*s[:2])]),
        "derivatives": lambda s: robot.inverse_dynamics_derivatives(*s).d_pose.ravel(),
        "jacobian": lambda s: robot.jacobian(s[0]).ravel(),
        "singularity": lambda s: robot.singularity(s[0]).type_two_singular_values,
        "configuration": lambda s: robot.configuration(s[0]),
        "batch": lambda s: robot.inverse_dynamics_batch(
            s[0][None], s[1][None], s[2][None], s[3][None], bounded=False).actuator_forces[0],
    }


@pytest.mark.parametrize("robot_type", [hp.Hexapod, hp.Planar3PRR])
def test_a_robot_shared_by_threads_answers_as_in_series(robot_type, fast_switching):
    robot = robot_type.default()
    states = _states(robot, np.random.default_rng(11))
    for name, call in _calls(robot).items():
        serial = [call(s) for s in states]
        jobs = states * 4
        with ThreadPoolExecutor(4) as pool:
            threaded = list(pool.map(call, jobs))
        for k, got in enumerate(threaded):
            np.testing.assert_array_equal(got, serial[k % N_STATES], err_msg=name)


def test_lazy_result_parts_read_in_other_threads(fast_switching):
    """Results made in one thread and read (lazily) in others, while the robot keeps
    computing: the lazy parts hold the robot's lock."""
    robot = hp.Hexapod.default()
    states = _states(robot, np.random.default_rng(12))
    results = [robot.inverse_dynamics(*s, bounded=False) for s in states]
    expected = [hp.Hexapod.default().inverse_dynamics(*s, bounded=False) for s in states]

    def read(k):
        robot.forward_dynamics(states[k][0], states[k][1], np.zeros(6))   # keep it busy
        res = results[k]
        return np.concatenate([res.closure_forces.ravel(), [res.residual],
                               res.joint_wrenches["platform_joint"]])

    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(read, range(N_STATES)))
    for k in range(N_STATES):
        ref = expected[k]
        want = np.concatenate([ref.closure_forces.ravel(), [ref.residual],
                               ref.joint_wrenches["platform_joint"]])
        np.testing.assert_array_equal(got[k], want)


def test_the_compiled_fast_path_shared_by_threads(fast_switching):
    robot = hp.Hexapod.default()
    fast = fast_dynamics(robot)
    states = _states(robot, np.random.default_rng(13))
    serial = [fast.inverse_dynamics(*s, bounded=False) for s in states]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda s: fast.inverse_dynamics(*s, bounded=False),
                                 states * 4))
    for k, got in enumerate(threaded):
        np.testing.assert_array_equal(got, serial[k % N_STATES])


def test_the_generic_tree_routes_from_threads(fast_switching):
    """forward_dynamics_tree / inverse_dynamics_tree on one model from several threads
    (one workspace per thread)."""
    robot = hp.Hexapod.default()
    clm = robot.model
    states = []
    for s in _states(robot, np.random.default_rng(14)):
        res = robot.inverse_dynamics(s[0], s[1], s[2], bounded=False)
        states.append((res.configuration, res.velocity, res.acceleration, res.actuator_forces))

    def both(s):
        q, v, a, tau = s
        fwd = forward_dynamics_tree(clm, q, v, tau, method="kkt")
        inv = inverse_dynamics_tree(clm, q, v, a, method="kkt")
        return np.concatenate([fwd.a, inv.actuator_forces])

    serial = [both(s) for s in states]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(both, states * 4))
    for k, got in enumerate(threaded):
        np.testing.assert_array_equal(got, serial[k % N_STATES])


def _generic_states(clm, rng, hexapod=None):
    """Closure-consistent states ``(q, v, u, tau_ext)`` of ``clm`` at rest (tau_ext on
    every other one): poses of ``hexapod`` when given, else actuated joints moved from
    the neutral configuration and the closures assembled."""
    out = []
    for k in range(N_STATES):
        if hexapod is not None:
            q = hexapod.configuration(random_pose(hexapod, rng))
        else:
            q = None
            while q is None:       # a draw a hair from a singular pose may not assemble
                dq = np.zeros(clm.nv)
                dq[clm.actuated_v] = 0.05 * rng.normal(size=clm.n_actuated)
                try:
                    q = clm.assemble(pin.integrate(clm.model, pin.neutral(clm.model), dq)).q
                except AssemblyError:
                    q = None
        ext = rng.normal(size=clm.nv) if k % 2 else None
        out.append((q, np.zeros(clm.nv), rng.normal(size=clm.n_actuated), ext))
    return out


def test_generic_pinocchio_route_and_lazy_multipliers_across_threads(fast_switching):
    """The "pinocchio" forward route (its generalised-force buffer, Pinocchio's buffers,
    the multipliers converted when read) from several threads on one model, and results
    made in one thread read in others while those compute: bit for bit the answers of a
    model that nobody else uses. Cassie has redundant rows (minimum-norm multipliers),
    the hexapod independent ones (Pinocchio's, converted)."""
    rng = np.random.default_rng(15)
    hexapod = hp.Hexapod.default()
    for clm, fresh, states in (
            (hexapod.model, hp.Hexapod.default().model,
             _generic_states(hexapod.model, rng, hexapod)),
            (robots.cassie(), robots.cassie(), None)):
        states = states or _generic_states(clm, rng)
        expected = [forward_dynamics_tree(fresh, *s) for s in states]
        # made here, read in the pool while this thread keeps computing on the workspace
        # that made them (each read converts on that workspace's conversion data)
        made = [forward_dynamics_tree(clm, *s) for s in states]

        def work(k, clm=clm, states=states, made=made):
            res = forward_dynamics_tree(clm, *states[(k + 5) % N_STATES])    # keep busy
            return np.concatenate([res.a, res.multipliers, made[k].multipliers])

        with ThreadPoolExecutor(4) as pool:
            jobs = [pool.submit(work, k % N_STATES) for k in range(4 * N_STATES)]
            while not all(job.done() for job in jobs):
                forward_dynamics_tree(clm, *states[0])
            got = [job.result() for job in jobs]
        for k, row in enumerate(got):
            other = expected[(k + 5) % N_STATES]
            want = np.concatenate([other.a, other.multipliers,
                                   expected[k % N_STATES].multipliers])
            np.testing.assert_array_equal(row, want)
