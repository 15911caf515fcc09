"""rventry: hypersonic entry guidance research on the rv-Euler parameterization.

Rooms, each importing only from the rooms before it:

* :mod:`rventry_env.core` - Euler parameters, rv-Euler equations of motion, conversions;
* :mod:`rventry_env.physics` - force-model parts and the entry dynamics;
* :mod:`rventry_env.task` - the paper's Example 2 problem, the control step, the success
  thresholds and the dispersion sets (no Gymnasium);
* :mod:`rventry_env.envs` - the ``RvEntry-v0`` Gymnasium environment (single and vector);
  :mod:`rventry_env.reference` - LGR collocation and the shipped optimal reference;
  :mod:`rventry_env.validation` - the model-validation loop on measured flight data;
* :mod:`rventry_env.guidance` - guidance laws: reference replay, TV-LQR, estimation, re-planning;
* :mod:`rventry_env.evaluation` - rollouts, summaries, plots, ``rventry evaluate`` / ``compare``.

The learning agents live in the separate package ``rventry_agents``, which this
library never imports.

``import rventry_env`` does not import Gymnasium, so the physics and the solvers
load without it. ``RvEntry-v0`` is registered the moment Gymnasium is imported
(before or after this package): ``gym.make("RvEntry-v0")`` works in either order.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys

__version__ = "0.2.0"


class _RegisteringLoader(importlib.abc.Loader):
    """Gymnasium's own loader, which registers ``RvEntry-v0`` once Gymnasium's module has executed."""

    def __init__(self, inner):
        self.inner = inner

    def create_module(self, spec):
        return self.inner.create_module(spec)

    def exec_module(self, module):
        self.inner.exec_module(module)
        from rventry_env.envs import register_envs

        register_envs()


class _GymnasiumFinder(importlib.abc.MetaPathFinder):
    """Finds Gymnasium once, wraps its loader in :class:`_RegisteringLoader`, and removes itself."""

    def find_spec(self, fullname, path, target=None):
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _RegisteringLoader(spec.loader)
        return spec


def _register_on_gymnasium_import() -> None:
    """Register ``RvEntry-v0`` now if Gymnasium is loaded, else as soon as it is.

    This is the one thing importing the package does beyond defining names, and it is
    deliberate: the physics and the solvers load without Gymnasium, yet ``gym.make("RvEntry-v0")``
    works in either import order, as a Gymnasium environment package's users expect. The finder
    on ``sys.meta_path`` acts on the import of ``gymnasium`` alone, once, and then removes itself.
    """
    if "gymnasium" in sys.modules:
        from rventry_env.envs import register_envs

        register_envs()
        return
    if not any(isinstance(f, _GymnasiumFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _GymnasiumFinder())


_register_on_gymnasium_import()
