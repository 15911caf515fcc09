"""An entry model: the force-model parts the entry dynamics are built from."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from rventry_env.physics.atmosphere import Atmosphere, ExponentialAtmosphere
from rventry_env.physics.checks import check_part
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

    def __post_init__(self):
        if not isinstance(self.planet, Planet):
            raise ValueError(f"EntryModel.planet must be a Planet, got {self.planet!r:.80}")
        if not isinstance(self.vehicle, Vehicle):
            raise ValueError(f"EntryModel.vehicle must be a Vehicle (mass, reference area, aerodynamics), "
                             f"got {self.vehicle!r:.80}")  # fmt: skip
        check_part(self, "gravity", "acceleration_a")
        check_part(self, "atmosphere", "density", "speed_of_sound")
        check_part(self, "wind", "velocity_a", optional=True)

    def replace(self, **changes) -> "EntryModel":
        """A copy with some parts replaced."""
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict:
        """A JSON-friendly description of every part (for reports)."""
        return _describe(self)


def scaled_model(model: EntryModel, density=1.0, lift=1.0, drag=1.0) -> EntryModel:
    """The model with its density and its lift and drag coefficients multiplied by factors.

    The factors may be numbers, per-vehicle NumPy arrays (the environments' dispersions) or
    CasADi expressions (a guidance law's estimates as NLP parameters). An accelerometer sees
    only the products: the drag acceleration scales with ``density * drag`` and the lift-to-drag
    ratio with ``lift / drag``; :func:`with_aero_scales` is the model those two numbers define.
    """
    from rventry_env.physics.aerodynamics import ScaledAerodynamics
    from rventry_env.physics.atmosphere import ScaledAtmosphere

    veh = model.vehicle
    return model.replace(
        atmosphere=ScaledAtmosphere(model.atmosphere, density),
        vehicle=dataclasses.replace(veh, aerodynamics=ScaledAerodynamics(veh.aerodynamics, lift, drag)),
    )


def with_aero_scales(model: EntryModel, drag_accel_scale=1.0, lift_to_drag_scale=1.0) -> EntryModel:
    """The model whose drag acceleration and lift-to-drag ratio are those of ``model`` times the factors.

    What an accelerometer can tell: it measures the aerodynamic specific force, so it
    fixes the drag acceleration (density x C_D x S / m) and the lift-to-drag ratio, but
    not how a drag error splits between density, C_D and mass. This model puts the drag
    factor on the density and the L/D factor on C_L; every force and acceleration then
    matches, while the dynamic pressure carries the whole drag factor (a guidance law
    keeps a margin on q for that).
    """
    return scaled_model(model, density=drag_accel_scale, lift=lift_to_drag_scale)


def numeric_leaves(obj) -> list:
    """Every number and array in a model, depth first through its parts' fields (tuples stay structure).

    With :func:`with_numeric_leaves` this splits a model into a fixed structure and its
    numbers, which the JAX environment carries as arrays in its params (so a tabulated
    profile, a per-vehicle array or a fitted factor is data, not compiled code).
    """
    if isinstance(obj, np.ndarray):
        return [obj]
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        return [obj]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return [leaf for f in dataclasses.fields(obj) for leaf in numeric_leaves(getattr(obj, f.name))]
    return []


def with_numeric_leaves(obj, leaves):
    """``obj`` with its :func:`numeric_leaves` replaced, in order, from the iterator ``leaves``.

    Parts are rebuilt without running their constructors' checks (the values may be
    traced JAX arrays); the structure was checked when ``obj`` was made.
    """
    if isinstance(obj, np.ndarray) or (isinstance(obj, (int, float)) and not isinstance(obj, bool)):
        return next(leaves)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        new = object.__new__(type(obj))
        for f in dataclasses.fields(obj):
            object.__setattr__(new, f.name, with_numeric_leaves(getattr(obj, f.name), leaves))
        return new
    return obj


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
