"""A vehicle type as the fleet workbook describes it (docs/interface.md, sheet ``Vehicles``).

This dataclass is the hand-over between the workbook reader (``fleetrun.workbook``), the
drive-cycle simulation (``fleetrun.simulation``) and the diagnosis at vehicle level.
Units are in the field names; EPA road-load coefficients stay in the units EPA publishes.
"""
from __future__ import annotations

import operator
from dataclasses import dataclass, field, fields

from fleetrun.differential import kim_torque_scale_Nm


# VehicleSpec fields that do not change how a vehicle drives a cycle (model_year does: it
# chooses a medium- or heavy-duty diesel's engine, fleetrun.simulation.heavy_duty_engine).
BOOKKEEPING_FIELDS = ("vehicle_id", "vehicle_class", "count", "annual_miles", "manufacturer", "make", "model")


@dataclass(frozen=True)
class VehicleSpec:
    vehicle_id: str
    vehicle_class: str
    duty_class: str                      # "LD", "MD" or "HD"
    configuration: str                   # canonical id, e.g. "LD_RWD"
    count: float
    annual_miles: float
    fuel: str                            # "gasoline" or "diesel"
    peak_engine_torque_Nm: float
    transmission: str                    # "automatic" or "manual"
    transmission_gear_ratios: tuple[float, ...]   # first gear first
    final_drive_ratio: float
    test_weight_kg: float
    coastdown_A_lbf: float
    coastdown_B_lbf_per_mph: float
    coastdown_C_lbf_per_mph2: float
    tire_size: str
    torque_converter_ratio: float | None = None   # default 3.0 automatic, 1.0 manual
    # Kim torque scale (thesis Sec. 5.2.1.A): the row's value, else set at construction to peak x
    # converter x first gear (fleetrun.differential.kim_torque_scale_Nm). dataclasses.replace of
    # those three fields keeps the old scale unless it passes kim_torque_scale_Nm=None.
    kim_torque_scale_Nm: float | None = None
    low_gear_ratio: float | None = None           # dual (two-speed) axles only
    rated_power_kW: float | None = None
    rated_speed_rpm: float | None = None
    engine_displacement_L: float | None = None
    lubricant: str | None = None
    # identification and powertrain details (optional; fleetrun import-epa fills them)
    manufacturer: str | None = None
    make: str | None = None
    model: str | None = None
    model_year: int | None = None
    gearbox_type: str | None = None      # automatic, automated_manual, cvt, manual
    converter_lockup: str | None = None  # "yes" / "no"
    cylinders: int | None = None
    nv_ratio_rpm_per_mph: float | None = None   # EPA N/V: engine rpm per mph in top gear
    technology: str | None = None        # comma list of fleetrun.simulation.technology names
    measured_ftp_mpg: float | None = None  # measured FTP composite: calibrates the vehicle's efficiency
    label_combined_mpg: float | None = None   # EPA label combined, used when no measured FTP
    label_group: str | None = None       # rows sharing one label: one fuel scale (simulation/measured.py)
    label_city_mpg: float | None = None      # EPA label city and highway: with both, the city-and-highway
    label_highway_mpg: float | None = None   # route of simulation/measured.py (used when no measured FTP)
    extra: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        if self.kim_torque_scale_Nm is None and self.transmission_gear_ratios:
            object.__setattr__(self, "kim_torque_scale_Nm", float(kim_torque_scale_Nm(
                self.peak_engine_torque_Nm, self.converter_ratio, max(self.transmission_gear_ratios))))
        elif self.kim_torque_scale_Nm is not None:
            object.__setattr__(self, "kim_torque_scale_Nm", float(self.kim_torque_scale_Nm))

    def physics_key(self) -> tuple:
        """What decides how the vehicle drives a cycle: every field but BOOKKEEPING_FIELDS
        (rows equal in this key simulate once)."""
        extra = tuple(sorted((k, repr(x)) for k, x in self.extra.items())) if self.extra else ()
        return _physics_fields(self), extra

    @property
    def converter_ratio(self) -> float:
        if self.torque_converter_ratio is not None:
            return float(self.torque_converter_ratio)
        return 3.0 if self.transmission == "automatic" else 1.0


# the fields physics_key compares, read in one call (the key is built for every row of a fleet)
_physics_fields = operator.attrgetter(*(f.name for f in fields(VehicleSpec)
                                        if f.name not in BOOKKEEPING_FIELDS and f.name != "extra"))


_FIELD_NAMES = tuple(f.name for f in fields(VehicleSpec))


def vehicle_from_fields(values: dict) -> VehicleSpec:
    """``VehicleSpec(**values)``. Where ``values`` holds every field in the class's order (as
    the workbook reader's rows do), the same object (same ``__dict__``, same ``__post_init__``)
    is made without the frozen dataclass's ``__init__``, which sets each field through
    ``object.__setattr__`` (a 7,600-row fleet: 0.07 s of reading); any other ``values`` go
    through ``__init__`` (its defaults and its TypeError)."""
    if tuple(values) != _FIELD_NAMES:
        return VehicleSpec(**values)
    spec = object.__new__(VehicleSpec)
    spec.__dict__.update(values)
    spec.__post_init__()
    return spec
