"""An entry model: the force-model parts the entry dynamics are built from."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from rventry_env.physics.atmosphere import Atmosphere, ExponentialAtmosphere
from rventry_env.physics.gravity import Gravity, PointMassGravity
from rventry_env.physics.planet import Planet
from rventry_env.physics.vehicle import Vehicle
from rventry_env.physics.wind import Wind


@dataclass(frozen=True)
class EntryModel:
    """Planet, gravity, atmosphere, vehicle (with its aerodynamics) and wind.

    Each part is swappable; the defaults are those of docs/conventions.md. Parts are frozen
    dataclasses, so a model is a value: derive variants with :meth:`replace`.

    :param planet: radius, mu and rotation of the observation frame E.
    :param gravity: a :class:`~rventry_env.physics.gravity.Gravity`.
    :param atmosphere: an :class:`~rventry_env.physics.atmosphere.Atmosphere`.
    :param vehicle: mass, reference area and aerodynamic coefficients.
    :param wind: ``None`` (still air) or a :class:`~rventry_env.physics.wind.Wind`.
    """

    planet: Planet = field(default_factory=Planet)
    gravity: Gravity = field(default_factory=PointMassGravity)
    atmosphere: Atmosphere = field(default_factory=ExponentialAtmosphere)
    vehicle: Vehicle = field(default_factory=Vehicle)
    wind: Wind | None = None

    def replace(self, **changes) -> "EntryModel":
        """A copy with some parts replaced."""
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict:
        """A JSON-friendly description of every part (for reports)."""
        return _describe(self)


def _describe(obj):
    if dataclasses.is_dataclass(obj):
        out = {"type": type(obj).__name__}
        for f in dataclasses.fields(obj):
            if f.name.startswith("_"):
                continue
            out[f.name] = _describe(getattr(obj, f.name))
        return out
    if isinstance(obj, (list, tuple)):
        return [_describe(v) for v in obj]
    if hasattr(obj, "tolist"):
        return obj.tolist()
    return obj
