"""The records a simulation hands across module boundaries (typed, frozen).

- :class:`StepResults`: one backward pass, step by step (``core.backward`` -> ``simulate``);
- :class:`BlockSums`: one block of vehicles summed over the cycle (inside ``simulate``);
- :class:`Trace`: the per-step trace ``simulate(..., trace=True)`` returns, one field per
  column of the trace CSV (docs/interface.md);
- :class:`PhaseResult`, :class:`FleetCycleResult`: what ``simulate`` returns.

Both sides import them from here, so a field added or renamed is one edit that every reader
sees. Arrays are vehicles x steps (V, N) or per vehicle (V,); the records are frozen (no field
is rebound), the arrays they hold are numpy arrays as computed.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np
import pandas as pd

from fleetrun.effects.base import AppliedEffect
from fleetrun.errors import FleetrunError
from fleetrun.fileio import JsonDocument

__all__ = ["StepResults", "BlockSums", "Trace", "PhaseResult", "FleetCycleResult", "TRACE_COLUMNS",
           "SUM_FIELDS", "PHASE_FIELDS"]


@dataclass(frozen=True, eq=False)
class StepResults:
    """One backward pass (``fleetrun.simulation.core.backward``): (V, N) arrays, or (1, N) for
    the step motion when every vehicle drives the same speeds. The three losses are None unless
    the pass was asked for them (a traced simulation)."""

    dt: np.ndarray                            # step length [s]
    v_avg: np.ndarray                         # mean speed of the step [m/s]
    accel: np.ndarray                         # acceleration [m/s2]
    grade: np.ndarray                         # mean grade [%]
    force: np.ndarray                         # tractive force [N]
    moving: np.ndarray                        # mean speed above 1e-6 m/s
    wheel_torque_Nm: np.ndarray
    wheel_speed_rpm: np.ndarray
    gear: np.ndarray
    axle_low: np.ndarray                      # two-speed axle in its low range
    diff_input_torque_Nm: np.ndarray
    diff_input_speed_rpm: np.ndarray
    diff_efficiency: np.ndarray | None        # None unless losses were asked for
    transmission_input_torque_Nm: np.ndarray
    transmission_input_speed_rpm: np.ndarray
    converter_unlocked: np.ndarray
    engine_speed_rpm: np.ndarray
    engine_torque_Nm: np.ndarray
    engine_max_torque_Nm: np.ndarray
    infeasible: np.ndarray                    # demand above full load
    fuel_rate_g_per_s: np.ndarray
    wheel_power_W: np.ndarray
    engine_power_W: np.ndarray
    diff_loss_W: np.ndarray | None = None
    transmission_loss_W: np.ndarray | None = None
    converter_loss_W: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Trace:
    """The per-step trace of every vehicle (V, N) arrays; the field order is the column order
    of the trace CSV (the documented columns first, then extras; docs/interface.md)."""

    time_s: np.ndarray
    vehicle_speed_mps: np.ndarray
    wheel_torque_Nm: np.ndarray
    diff_input_torque_Nm: np.ndarray
    diff_input_speed_rpm: np.ndarray
    diff_efficiency: np.ndarray
    gear: np.ndarray
    engine_speed_rpm: np.ndarray
    engine_torque_Nm: np.ndarray
    fuel_rate_g_per_s: np.ndarray
    target_speed_mps: np.ndarray
    grade_pct: np.ndarray
    tractive_force_N: np.ndarray
    wheel_speed_rpm: np.ndarray
    axle_range: np.ndarray                    # "low" / "high"
    transmission_input_torque_Nm: np.ndarray
    transmission_input_speed_rpm: np.ndarray
    converter_unlocked: np.ndarray
    engine_max_torque_Nm: np.ndarray
    wheel_power_W: np.ndarray
    diff_loss_W: np.ndarray
    transmission_loss_W: np.ndarray
    converter_loss_W: np.ndarray
    engine_power_W: np.ndarray
    not_followed: np.ndarray
    phase: np.ndarray                         # the composed cycle's phase name ("" outside one)
    engine_temp_C: np.ndarray
    cold_start_fuel_g_per_s: np.ndarray

    def columns(self) -> dict[str, np.ndarray]:
        """Column name -> (V, N) array, in the trace CSV's order."""
        return {name: getattr(self, name) for name in TRACE_COLUMNS}


TRACE_COLUMNS = tuple(f.name for f in fields(Trace))


@dataclass(frozen=True, eq=False)
class BlockSums:
    """One block of vehicles summed over the cycle (V,) (phase sums (V, phases)); ``behind``
    marks vehicles with steps above full load (re-driven); the trace if asked for."""

    miles: np.ndarray
    fuel_g: np.ndarray
    fuel_gal: np.ndarray
    mpg: np.ndarray
    diff_input_energy_J: np.ndarray
    diff_output_energy_J: np.ndarray
    drivetrain_input_energy_J: np.ndarray
    wheel_energy_J: np.ndarray
    engine_energy_J: np.ndarray
    shortfall_time_s: np.ndarray
    shortfall_distance_m: np.ndarray
    shortfall_max_speed_mps: np.ndarray
    shortfall_steps: np.ndarray
    behind: np.ndarray
    phase_fuel_g: np.ndarray                  # (V, phases); one phase for a plain cycle
    phase_miles: np.ndarray
    trace: Trace | None = None


SUM_FIELDS = ("miles", "fuel_g", "fuel_gal", "mpg", "diff_input_energy_J", "diff_output_energy_J",
              "drivetrain_input_energy_J", "wheel_energy_J", "engine_energy_J", "shortfall_time_s",
              "shortfall_distance_m", "shortfall_max_speed_mps", "shortfall_steps")
PHASE_FIELDS = ("phase_fuel_g", "phase_miles")
BLOCK_ARRAYS = SUM_FIELDS + ("behind",) + PHASE_FIELDS


@dataclass(frozen=True, eq=False)
class PhaseResult:
    """One phase (bag) of a composed cycle, arrays over vehicles (V,)."""

    miles: np.ndarray
    fuel_g: np.ndarray
    fuel_gal: np.ndarray
    mpg: np.ndarray


@dataclass(frozen=True, eq=False)
class FleetCycleResult:
    """Per-vehicle results of one cycle (arrays of shape (V,)), and the trace if asked for.

    Energies are summed over steps "while driving" (wheel torque > 0, hence positive
    differential input torque), so ``diff_efficiency = diff_output / diff_input`` and
    ``drivetrain_efficiency = wheel / drivetrain_input`` are energy weighted and add over cycles.
    """
    vehicle_ids: list[str]
    cycle: str
    mode: str
    miles: np.ndarray
    fuel_g: np.ndarray
    fuel_gal: np.ndarray
    mpg: np.ndarray
    diff_input_energy_J: np.ndarray
    diff_output_energy_J: np.ndarray
    drivetrain_input_energy_J: np.ndarray
    wheel_energy_J: np.ndarray
    engine_energy_J: np.ndarray          # positive engine work over the whole cycle
    shortfall_time_s: np.ndarray         # time the vehicle ran more than 0.1 m/s below the trace
    shortfall_distance_m: np.ndarray     # trace distance minus distance driven
    shortfall_max_speed_mps: np.ndarray  # largest speed deficit
    shortfall_steps: np.ndarray          # steps with demand above full load (after re-drive)
    duration_s: float = 0.0
    trace: Trace | None = field(default=None, repr=False)
    # the --with effects and their parameters (fleetrun.simulation.effects.describe_effects)
    effects: list[AppliedEffect] = field(default_factory=list)
    # a composed cycle (FTP): phase name -> its results; then miles, fuel_g, fuel_gal and mpg
    # above are the composite (fleetrun.cycles.composite_per_mile)
    phases: dict[str, PhaseResult] = field(default_factory=dict)
    composite: str = ""

    @property
    def diff_efficiency(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.diff_output_energy_J / self.diff_input_energy_J

    @property
    def drivetrain_efficiency(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.wheel_energy_J / self.drivetrain_input_energy_J

    def summary(self, i: int = 0) -> JsonDocument:
        """The JSON line of ``fleetrun simulate`` for vehicle ``i`` (its keys: docs/interface.md)."""
        def f(x):
            x = float(x)
            return x if np.isfinite(x) else None
        return {
            "vehicle_id": self.vehicle_ids[i], "cycle": self.cycle, "mode": self.mode,
            "miles": f(self.miles[i]), "fuel_gal": f(self.fuel_gal[i]), "fuel_g": f(self.fuel_g[i]),
            "mpg": f(self.mpg[i]), "diff_efficiency": f(self.diff_efficiency[i]),
            "drivetrain_efficiency": f(self.drivetrain_efficiency[i]),
            "shortfall_time_s": f(self.shortfall_time_s[i]), "shortfall_distance_m": f(self.shortfall_distance_m[i]),
            "with": [asdict(e) for e in self.effects],
            **({"composite": self.composite,
                "phases": {p: {k.name: f(getattr(ph, k.name)[i]) for k in fields(PhaseResult)}
                           for p, ph in self.phases.items()}}
               if self.phases else {}),
        }

    def trace_frame(self, i: int = 0) -> pd.DataFrame:
        """Vehicle ``i``'s per-step trace as a pandas DataFrame (needs ``trace=True``)."""
        if self.trace is None:
            raise FleetrunError("no trace: simulate with trace=True")
        return pd.DataFrame({c: (a if np.ndim(a) == 1 else a[i]) for c, a in self.trace.columns().items()})


# ----------------------------------------------------------------------------- heavy duty
# Records of the heavy-duty modules (simulation/heavy_duty_engine.py, heavy_duty_shift.py;
# docs/validation-heavy-duty.md): the reference engine the SET is run on, the fuel-equation
# constants of a medium- or heavy-duty diesel, its economy shift speeds.

@dataclass(frozen=True)
class ReferenceEngine:
    """An engine's size and full-load shape (engine.full_load_torque_Nm's parameters)."""
    displacement_L: float
    peak_torque_Nm: float
    rated_power_kW: float
    rated_speed_rpm: float
    cylinders: int
    idle_speed_rpm: float
    peak_torque_speed_fraction: float
    idle_torque_fraction: float


@dataclass(frozen=True)
class HeavyDutyFuelConstants:
    """The eight constants of engine.py's fuel equation (params.FUEL_CONSTANTS names)."""
    eta_indicated: float
    high_load_factor: float
    fmep_0_kPa: float
    fmep_piston_speed_kPa_s_per_m: float
    fmep_peak_fraction: float
    pmep_throttle_kPa: float
    accessory_power_W: float
    transient_factor: float


@dataclass(frozen=True)
class EconomyShiftSpeeds:
    """Shift-schedule speeds of a heavy diesel [rpm] (params' transmission-set key names)."""
    shift_speed_min_rpm: float
    shift_speed_accel_rpm: float
    launch_speed_rpm: float


__all__ += ["ReferenceEngine", "HeavyDutyFuelConstants", "EconomyShiftSpeeds"]


@dataclass(frozen=True)
class EngineSet:
    """An engine parameter set of ``models/engines.toml`` (by fuel and duty class; the keys and
    their sources are documented there), the fitted fuel constants of
    ``models/engine_calibration.toml`` on top, and the fuel's properties (``models/fuels.toml``).
    Each may be overridden per vehicle by a Vehicles column of the same name."""
    eta_indicated: float
    high_load_factor: float
    fmep_0_kPa: float
    fmep_piston_speed_kPa_s_per_m: float
    fmep_peak_fraction: float
    pmep_throttle_kPa: float
    accessory_power_W: float
    transient_factor: float
    bmep_at_peak_kPa: float
    rated_speed_rpm: float
    idle_speed_rpm: float
    peak_torque_speed_fraction: float
    idle_torque_fraction: float
    rated_power_factor: float
    shift_speed_min_rpm: float
    power_reserve: float
    fuel_cut_speed_rpm: float
    lhv_MJ_per_kg: float
    density_kg_per_L: float


@dataclass(frozen=True)
class TransmissionSet:
    """A transmission parameter set of ``models/transmissions.toml`` (by gearbox type; keys and
    sources documented there). None: the set has no such value (the simulation's default)."""
    gear_efficiency: float
    spin_loss_Nm_at_0: float
    spin_loss_Nm_per_krpm: float
    direct_gear_efficiency: float | None = None
    stall_speed_rpm: float | None = None
    lockup_speed_rpm: float | None = None
    launch_speed_rpm: float | None = None
    shift_speed_min_rpm: float | None = None
    shift_speed_accel_rpm: float | None = None


@dataclass(frozen=True)
class ElectricConstants:
    """The battery-electric energy chain of ``models/electric.toml`` (sources there)."""
    drive_efficiency: float          # battery -> wheels [-]
    regen_efficiency: float          # wheels -> battery [-]
    regen_share: float               # share of the braking energy the motor takes [-]
    charging_efficiency: float       # wall -> battery [-]
    accessory_power_W: float         # while the car is on [W]


__all__ += ["EngineSet", "TransmissionSet", "ElectricConstants"]


@dataclass(frozen=True)
class LabelSplit:
    """How a label's fuel scale k is carried (models/technology.toml ``[label_split]``,
    fleetrun/simulation/measured.py): the HWFET at 25 C takes k^highway_share, every other
    cycle, ambient and scenario k^transfer_share (the FTP at 25 C takes k)."""

    highway_share: float
    transfer_share: float


@dataclass(frozen=True)
class LabelBlend:
    """A label's city and highway figures both given (models/technology.toml ``[label_split]``
    ``blend_*``): the FTP at 25 C takes the city figure's k_C; the HWFET at 25 C
    exp(weight log k_H + (1 - weight) highway_share log k), k_H the highway figure's scale and k
    the combined figure's (with ``highway_share``); every other cycle k^transfer_share."""

    highway_share: float
    weight: float
    transfer_share: float
