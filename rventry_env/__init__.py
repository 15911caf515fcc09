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

import sys

__version__ = "0.2.0"


def _register_on_gymnasium_import() -> None:
    """Register ``RvEntry-v0`` now if Gymnasium is loaded, else as soon as it is.

    A finder on ``sys.meta_path`` wraps Gymnasium's own loader; once Gymnasium's
    module has executed, the environment is registered and the finder removes
    itself. Nothing else is imported or changed.
    """
    if "gymnasium" in sys.modules:
        from rventry_env.envs import register_envs

        register_envs()
        return
    import importlib.abc
    import importlib.machinery

    class _Loader(importlib.abc.Loader):
        def __init__(self, inner):
            self.inner = inner

        def create_module(self, spec):
            return self.inner.create_module(spec)

        def exec_module(self, module):
            self.inner.exec_module(module)
            from rventry_env.envs import register_envs

            register_envs()

    class _Finder(importlib.abc.MetaPathFinder):
        def find_spec(self, fullname, path, target=None):
            if fullname != "gymnasium":
                return None
            sys.meta_path.remove(self)
            spec = importlib.machinery.PathFinder.find_spec(fullname, path)
            if spec is not None and spec.loader is not None:
                spec.loader = _Loader(spec.loader)
            return spec

    if not any(type(f).__name__ == "_Finder" and type(f).__module__ == __name__ for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


_register_on_gymnasium_import()
