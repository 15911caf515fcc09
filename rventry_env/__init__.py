"""rventry: hypersonic entry guidance research on the rv-Euler parameterization.

Layout (dependencies point one way, top to bottom):

* :mod:`rventry_env.core` - Euler parameters, rv-Euler equations of motion, conversions;
* :mod:`rventry_env.physics` - force-model parts and the entry dynamics;
* :mod:`rventry_env.envs` - the ``RvEntry-v0`` Gymnasium environment (single and vector);
* :mod:`rventry_env.reference` - LGR collocation and the shipped optimal reference;
* :mod:`rventry_env.validation` - the model-validation loop on measured flight data.
"""

__version__ = "0.1.0"

from rventry_env.envs import register_envs as _register_envs

_register_envs()
