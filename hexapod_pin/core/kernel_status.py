"""The status codes every robot's compiled kernels return: one numbering for all.

A kernel returns :data:`OK` or the first reason it could not answer; the robot's facade
turns a code into the library error that names the cause and the values (each robot its
own message, since only it knows which leg or link is at fault). Codes are plain ints so
that compiled (numba) code and the per-state code arrays of the batches share them.
"""

from __future__ import annotations

#: the answer was computed and passed the kernel's own checks
OK = 0
#: a chain cannot reach its platform joint
UNREACHABLE = 1
#: a type-I singularity (a chain's last link perpendicular to its actuator)
TYPE_I = 2
#: a universal joint in gimbal lock (a leg along its rail)
GIMBAL = 3
#: a type-II singularity (the closure matrix loses rank)
TYPE_II = 4
#: a mass matrix that is not positive definite
NOT_PD = 5
#: a non-finite input or intermediate value
NONFINITE = 6
#: an actuator outside its stroke
STROKE = 7
#: two carriages of a rail too close
GAP = 8
#: actuator forces beyond their bound
SATURATED = 9
#: a closed form that misses its own residual check (ill-conditioned near a singularity)
RESIDUAL = 10

#: relative residual above which a closed form refuses its own answer (:data:`RESIDUAL`):
#: the one tolerance of the compiled closed forms' verification and of the tree routes
#: (:mod:`~hexapod_pin.core.dynamics_common` imports it)
RESIDUAL_RTOL = 1e-9

#: every code, by name (messages and tests)
NAMES = {OK: "ok", UNREACHABLE: "unreachable", TYPE_I: "type_i", GIMBAL: "gimbal",
         TYPE_II: "type_ii", NOT_PD: "not_pd", NONFINITE: "nonfinite", STROKE: "stroke",
         GAP: "gap", SATURATED: "saturated", RESIDUAL: "residual"}
