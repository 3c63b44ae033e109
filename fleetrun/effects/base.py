"""What an effect is: physics the thesis model leaves out, with fixed parameter names.

Every differential-level effect in fleetrun is an *extra input torque loss* at the pinion,
``dT_in = coefficient * basis(channels; shape parameters)``: one parameter enters linearly
(the size of the effect) and at most one more sets its shape (a time constant, a speed
scale). That form is what lets ``fleetrun diagnose`` fit every candidate by least squares
and profile the shape parameter over a grid, and what lets ``fleetrun map --with`` and the
simulation add the same physics at steady state.

Vehicle-level effects are an *extra fuel rate* ``coefficient * basis`` in the same form.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np


@dataclass(frozen=True)
class AppliedEffect:
    """One effect as a run or simulation applied it (``--with``): its id, level and parameters
    (docs/effects.md); ``dataclasses.asdict`` gives the form of the JSON outputs' ``with``."""

    effect: str
    level: str
    parameters: dict[str, float]


@dataclass(frozen=True)
class Parameter:
    """One named parameter of an effect: bounds, the default ``--with`` uses, units."""

    name: str
    default: float
    lower: float
    upper: float
    unit: str
    meaning: str
    #: values tried when profiling a shape parameter in diagnose (empty: linear parameter)
    grid: tuple[float, ...] = ()


@dataclass(frozen=True)
class Effect:
    """A candidate physics: id, level, parameters, needed channels, signature, seed source.

    ``basis(channels, **shape)`` returns the effect per unit of the linear parameter (N m of
    extra input torque per unit at differential level, g/s of extra fuel per unit at vehicle
    level). ``channels`` maps channel names to numpy arrays: ``input_torque_Nm``, ``input_speed_rad_s``,
    ``input_accel_rad_s2``, ``wheel_speed_difference_rad_s``, ``time_s``, ``ambient_temp_C``,
    ``gear_ratio``, ``lubricant`` and the extra ones an effect lists in ``channels`` (built from a
    recording by :mod:`fleetrun.diagnose.differential`, at steady state by
    :func:`fleetrun.effects.steady_channels`).
    """

    id: str
    level: str                      # "differential" or "vehicle"
    title: str
    parameters: tuple[Parameter, ...]
    linear: str                     # the parameter that scales the basis
    channels: tuple[str, ...]       # channels the effect needs beyond time/torque/speed
    signature: str                  # what it looks like in a residual
    seed: str                       # where the physics comes from
    steady_state: str               # how it behaves in a steady-state map
    basis: Callable[..., np.ndarray] = field(repr=False, compare=False, default=None)
    #: other effects it can masquerade as when its own channel is missing
    confounded_with: tuple[str, ...] = ()
    #: the measurement that would separate it from its confounders
    separating_test: str = ""
    #: a condition of each recording (a cold start), not a property of the vehicle: when
    #: several recordings are diagnosed together (:mod:`fleetrun.diagnose.joint`) it gets its
    #: own parameters in each recording instead of one set for all
    per_recording: bool = False

    @property
    def shape(self) -> tuple[Parameter, ...]:
        """The non-linear (shape) parameters, profiled over their grid in diagnose."""
        return tuple(p for p in self.parameters if p.name != self.linear)

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def defaults(self) -> dict[str, float]:
        return {p.name: p.default for p in self.parameters}

    def evaluate(self, channels: Mapping[str, np.ndarray], params: Mapping[str, float]) -> np.ndarray:
        """The effect for full parameters: ``params[linear] * basis(channels, **shape)``."""
        full = self.defaults()
        full.update(params)
        shape = {p.name: full[p.name] for p in self.shape}
        return full[self.linear] * self.basis(channels, **shape)

    def missing_channels(self, available) -> list[str]:
        return [c for c in self.channels if c not in available]
