"""rv-Euler core: Euler parameters, equations of motion, conversions.

Pure numerical functions on plain arrays (or CasADi expressions): no classes with
state, no units, no I/O.
"""

from rventry_env.core.backend import NUMPY, casadi_ns
from rventry_env.core.eom import STATE_NAMES, rv_euler_rates, rv_euler_rhs, two_body_rhs

__all__ = ["NUMPY", "casadi_ns", "STATE_NAMES", "rv_euler_rates", "rv_euler_rhs", "two_body_rhs"]
