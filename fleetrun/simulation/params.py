"""Per-vehicle simulation parameters: the Vehicles row, defaults and overrides, as arrays.

Every default comes from ``models/engines.toml`` (by fuel and duty class) or
``models/transmissions.toml`` (by transmission type) and may be overridden per vehicle by a
key of the same name in ``VehicleSpec.extra``. Derived defaults (documented in
docs/simulation.md):

- displacement [L] = 4 pi T_peak / bmep_at_peak (when ``engine_displacement_L`` is blank);
- rated speed from the set; rated power = rated_power_factor x T_peak x omega_rated;
- torque-converter stall torque ratio = ``VehicleSpec.converter_ratio`` (the thesis'
  "maximum torque converter torque ratio", Sec. 5.2.1.C, default 3.0 automatic);
- the fuel-equation constants (``fleetrun/simulation/engine.py``) of light-duty engines from
  the fleet-wide calibration ``models/engine_calibration.toml`` where it has them;
- cylinders (when blank): the nearest of 3, 4, 6, 8 to displacement / 0.55 L; stroke = bore;
- the gearbox kind: the optional ``gearbox_type`` column (automatic, automated_manual, cvt,
  manual), else ``transmission``; a ``converter_lockup`` of ``no`` keeps the converter unlocked.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from operator import attrgetter, itemgetter
from typing import Sequence

import numpy as np

from fleetrun.differential import dual_configuration_ids
from fleetrun.errors import FleetrunError, InputError
from fleetrun.physics.fuels import fuel_properties
from fleetrun.resources import model_file, models_dir
from fleetrun.simulation.engine import stroke_m
from fleetrun.simulation.heavy_duty_engine import heavy_duty_fuel_constants
from fleetrun.simulation.heavy_duty_shift import heavy_duty_shift_speeds
from fleetrun.simulation.records import EngineSet, TransmissionSet
from fleetrun.simulation.road_load import ROTATING_MASS_FRACTION, coastdown_to_si
from fleetrun.simulation.technology import TECHNOLOGIES, parse_technology
from fleetrun.simulation.tyre import rolling_radius_m
from fleetrun.units import RAD_S_PER_RPM
from fleetrun.vehicle import VehicleSpec

DUAL_CONFIGURATIONS = frozenset(dual_configuration_ids())  # models/configurations.toml


CALIBRATION_FILE = "engine_calibration.toml"
GEARBOX_TYPES = ("automatic", "automated_manual", "cvt", "manual")
FUEL_CONSTANTS = ("eta_indicated", "high_load_factor", "fmep_0_kPa", "fmep_piston_speed_kPa_s_per_m",
                  "fmep_peak_fraction", "pmep_throttle_kPa", "accessory_power_W", "transient_factor")


def engine_defaults(fuel: str, duty_class: str) -> EngineSet:
    """The engine set of ``models/engines.toml`` for the fuel and duty class, with the fitted
    constants of ``models/engine_calibration.toml`` (``[<fuel>.<duty>.constants]``) on top.

    Parameters
    ----------
    fuel : str, ``gasoline`` or ``diesel``
    duty_class : str, ``LD``, ``HD`` ... (a duty of the fuel's table; another falls back to ``LD``)

    Returns
    -------
    EngineSet, the defaults with the fuel's lower heating value [MJ/kg] and density [kg/L].
    """
    return _engine_set(fuel, duty_class)


@lru_cache(maxsize=64)
def _engine_set(fuel: str, duty_class: str) -> EngineSet:
    """engine_defaults, once per (fuel, duty class) in a process (the files are read once too,
    resources.model_file; an EngineSet is frozen)."""
    sets = model_file("engines.toml")
    if fuel not in sets:
        raise InputError(f"unknown fuel '{fuel}'", column="fuel", value=fuel,
                         hint="Use gasoline or diesel")
    by_duty = sets[fuel]
    duty = duty_class if duty_class in by_duty else "LD"
    values = dict(by_duty[duty])
    fuel_props = fuel_properties(fuel)
    values.update(lhv_MJ_per_kg=fuel_props.lhv_MJ_per_kg, density_kg_per_L=fuel_props.density_kg_per_L)
    if (models_dir() / CALIBRATION_FILE).exists():
        fitted = model_file(CALIBRATION_FILE).get(fuel, {}).get(duty, {}).get("constants", {})
        values.update({key: fitted[key]["value"] for key in FUEL_CONSTANTS if key in fitted})
    return EngineSet(**values)


def transmission_defaults(gearbox_type: str) -> TransmissionSet:
    """The transmission set of ``models/transmissions.toml`` for the gearbox type.

    Parameters
    ----------
    gearbox_type : str, one of ``GEARBOX_TYPES``

    Returns
    -------
    TransmissionSet, the type's defaults.
    """
    return _transmission_set(gearbox_type)


@lru_cache(maxsize=64)
def _transmission_set(gearbox_type: str) -> TransmissionSet:
    """transmission_defaults, once per gearbox type in a process (a TransmissionSet is frozen)."""
    sets = model_file("transmissions.toml")
    if gearbox_type not in sets:
        raise InputError(f"unknown gearbox_type '{gearbox_type}'", column="gearbox_type",
                         value=gearbox_type, hint="Use " + ", ".join(GEARBOX_TYPES))
    return TransmissionSet(**sets[gearbox_type])


def gearbox_type(v: VehicleSpec) -> str:
    """The optional ``gearbox_type`` column, else the documented ``transmission`` (docs/interface.md) (automatic/manual).

    Parameters
    ----------
    v : VehicleSpec, a Vehicles row

    Returns
    -------
    str, one of ``GEARBOX_TYPES`` or the ``transmission`` value.
    """
    value = column_value(v, "gearbox_type")
    if value is None or (isinstance(value, float) and math.isnan(value)) or str(value).strip() == "":
        return v.transmission
    text = str(value).strip().lower().replace("-", "_").replace(" ", "_")
    if text not in GEARBOX_TYPES:
        raise InputError(f"vehicle '{v.vehicle_id}': unknown gearbox_type '{value}'", column="gearbox_type",
                         value=value, hint="Use " + ", ".join(GEARBOX_TYPES))
    return text


def column_value(v: VehicleSpec, key: str):
    """A Vehicles column's value: the VehicleSpec field of that name (schema columns, e.g. the
    optional gearbox_type, converter_lockup, cylinders) or else the extra column, or None.

    Parameters
    ----------
    v : VehicleSpec, a Vehicles row
    key : str, the column name

    Returns
    -------
    the cell's value as read, or None.
    """
    value = getattr(v, key, None) if key in VehicleSpec.__dataclass_fields__ else None
    return (v.extra or {}).get(key) if value is None else value


def _yes_no(v: VehicleSpec, key: str, default: bool) -> bool:
    value = column_value(v, key)
    if value is None or (isinstance(value, float) and math.isnan(value)) or str(value).strip() == "":
        return default
    text = str(value).strip().lower()
    if text in ("yes", "y", "true", "1"):
        return True
    if text in ("no", "n", "false", "0"):
        return False
    raise InputError(f"vehicle '{v.vehicle_id}': {key} must be yes or no", column=key, value=value,
                     hint="Write yes or no")


def default_cylinders(displacement_L: float) -> int:
    """The nearest of 3, 4, 6, 8 cylinders to displacement / 0.55 L (light-duty practice:
    0.45-0.65 L per cylinder).

    Parameters
    ----------
    displacement_L : float, engine displacement [L]

    Returns
    -------
    int, the number of cylinders.
    """
    return min((3, 4, 6, 8), key=lambda c: abs(c - displacement_L / 0.55))


CVT_STEPS = 12  # a CVT's range as geometric steps for the full-load table and the first guess


def canonical(configuration: str) -> str:
    """A configuration id in canonical spelling: upper case, ``_`` for ``-``.

    Parameters
    ----------
    configuration : str, a configuration id in any case, with ``-`` or ``_``

    Returns
    -------
    str, the canonical id.
    """
    return str(configuration).strip().upper().replace("-", "_")


def _check(v: VehicleSpec) -> None:
    def bad(column, value, what, hint):
        raise InputError(f"vehicle '{v.vehicle_id}': {column} {what}", column=column, value=value, hint=hint)

    gears = tuple(v.transmission_gear_ratios or ())
    if len(gears) == 0:
        bad("transmission_gear_ratios", gears, "is empty", "Give the gear ratios, first gear first, e.g. 4.17,2.34,1.52,1.14,0.87,0.69")
    if any((not math.isfinite(g)) or g <= 0 for g in gears):
        bad("transmission_gear_ratios", gears, "must be positive numbers", "Give the gear ratios, first gear first")
    for column in ("peak_engine_torque_Nm", "final_drive_ratio", "test_weight_kg"):
        value = getattr(v, column)
        if value is None or not math.isfinite(float(value)) or float(value) <= 0:
            bad(column, value, "must be a positive number", "Fix the value in the Vehicles row")
    if canonical(v.configuration) in DUAL_CONFIGURATIONS:
        if v.low_gear_ratio is None or not float(v.low_gear_ratio) > 1.0:
            bad("low_gear_ratio", v.low_gear_ratio, "must be given (> 1) for a dual (two-speed) axle",
                "Give the two-speed axle's low range ratio, e.g. 1.36")


@dataclass
class VehicleArrays:
    """Per-vehicle parameters as arrays of shape (V,) (ratios (V, K))."""
    n: int
    configuration: list
    mass_kg: np.ndarray
    rot_frac: np.ndarray
    A_N: np.ndarray
    B_N: np.ndarray
    C_N: np.ndarray
    radius_m: np.ndarray
    final_drive: np.ndarray
    low_ratio: np.ndarray        # 1 for single-speed axles
    kim_torque_scale_Nm: np.ndarray
    # gear table: combinations of transmission gear x axle range, largest overall first
    combo_trans_ratio: np.ndarray   # (V, K) transmission ratio (0 padding)
    combo_axle_low: np.ndarray      # (V, K) bool
    combo_gear: np.ndarray          # (V, K) 1-based transmission gear (int16: per-step gathers stay small)
    combo_gear_eff: np.ndarray      # (V, K)
    n_combos: np.ndarray
    automatic: np.ndarray           # bool: torque converter (automatic and CVT)
    cvt: np.ndarray                 # bool: continuously variable (ratio range = first..last combo)
    cvt_ratio_range: np.ndarray     # (V, 2) largest, smallest transmission ratio (CVT rows)
    has_lockup: np.ndarray          # bool: the converter has a lock-up clutch
    spin_loss: np.ndarray           # (V, 2) gearbox spin loss a [N m], b [N m per 1000 rpm]
    stall_TR: np.ndarray
    K_tc: np.ndarray
    lockup_rpm: np.ndarray
    launch_rpm: np.ndarray
    # engine
    T_peak: np.ndarray
    P_rated_kW: np.ndarray
    n_rated: np.ndarray
    n_idle: np.ndarray
    n_peak_torque: np.ndarray
    idle_T_frac: np.ndarray
    displacement_L: np.ndarray
    stroke_m: np.ndarray
    throttled: np.ndarray           # bool: spark ignition (gasoline)
    fuel_constants: np.ndarray      # (V, 8) params.FUEL_CONSTANTS (engine.fuel_coefficients)
    lhv: np.ndarray
    density: np.ndarray
    shift_min_rpm: np.ndarray
    shift_accel_rpm: np.ndarray     # lowest engine speed while accelerating
    power_reserve: np.ndarray
    fuel_cut_rpm: np.ndarray
    idle_fuel_g_s: np.ndarray       # NaN: from the Willans line
    fuel: list                      # "gasoline" / "diesel" (vehicle-level effects price extra work by it)
    technology: np.ndarray | None = None   # (V, len(TECHNOLOGIES)) bool (simulation/technology.py)
    power_table: np.ndarray | None = None   # filled by the simulation on first use
    idle_fuel_rate: np.ndarray | None = None   # [g/s] idem (simulation.core.idle_fuel_rate_g_per_s)

    def subset(self, rows) -> "VehicleArrays":
        """The same parameters for the vehicles ``rows`` (indices, or a slice) only. A run of
        consecutive indices gives views of these arrays (the same values, no copies; nothing
        writes into a VehicleArrays' arrays)."""
        rows = _as_slice(rows, self.n)
        if isinstance(rows, slice):
            n, pick = len(range(*rows.indices(self.n))), (lambda a: a[rows])
        else:
            n, listed = rows.size, rows.tolist()
            pick = lambda a: [a[i] for i in listed]  # noqa: E731
        values = {}
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if name == "n":
                value = n
            elif isinstance(value, np.ndarray):
                value = value[rows]
            elif isinstance(value, list):
                value = pick(value)
            values[name] = value
        return VehicleArrays(**values)


def _as_slice(rows, n: int):
    """``rows`` (vehicle indices) as a slice when they are consecutive and ascending, else as
    an index array."""
    if isinstance(rows, slice):
        return rows
    rows = np.asarray(rows)
    if rows.ndim == 1 and rows.size and rows.dtype.kind in "iu" and 0 <= rows[0] and rows[-1] < n \
            and rows[-1] - rows[0] == rows.size - 1 and (rows.size == 1 or bool((np.diff(rows) == 1).all())):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows


_SPEC_FIELDS = frozenset(VehicleSpec.__dataclass_fields__)
assert not _SPEC_FIELDS & set(FUEL_CONSTANTS)   # _row reads them from the set or the extra columns only
_fuel_constants_of = attrgetter(*FUEL_CONSTANTS)   # an EngineSet's, in FUEL_CONSTANTS order


def _get(v: VehicleSpec, key: str, default):
    """The number in the column ``key`` (column_value), else ``default`` (blank or NaN)."""
    value = getattr(v, key) if key in _SPEC_FIELDS else None
    if value is None:
        if not v.extra:   # most rows: no extra column, the default (column_value without the calls)
            return default
        value = v.extra.get(key)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return default
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"vehicle '{v.vehicle_id}': {key} must be a number", column=key, value=value) from None


def vehicle_arrays(vehicles: Sequence[VehicleSpec]) -> VehicleArrays:
    """Check the rows and gather their parameters (defaults filled in) into arrays.

    Parameters
    ----------
    vehicles : sequence of VehicleSpec, the Vehicles rows (V of them)

    Returns
    -------
    VehicleArrays, the parameters as arrays of shape (V,) (SI units and rpm as the field names
    say); a row the simulation refuses raises a :class:`FleetrunError` (:func:`refused_vehicles`).
    """
    rows = [_row_cached(v) for v in vehicles]
    return _gather(rows)


def willans_slope(vehicles: Sequence[VehicleSpec] | VehicleArrays) -> np.ndarray:
    """Each vehicle's ``eta_indicated`` (Willans-line slope of its fuel equation, defaults,
    calibration and per-vehicle overrides filled in): what extra engine work costs
    (fleetrun.effects.vehicle.marginal_fuel_g_per_J).

    Parameters
    ----------
    vehicles : sequence of VehicleSpec or VehicleArrays, the vehicles

    Returns
    -------
    Willans-line slope ``eta_indicated`` [-] per vehicle, shape (V,).
    """
    va = vehicles if isinstance(vehicles, VehicleArrays) else vehicle_arrays(vehicles)
    return va.fuel_constants[:, FUEL_CONSTANTS.index("eta_indicated")]


ROW_CACHE_SIZE = 65536   # vehicles whose checked parameters a process keeps (the oldest go first)
_ROWS: dict = {}         # VehicleSpec.physics_key() -> _row's parameters


def _row_cached(v: VehicleSpec, key: tuple | None = None) -> dict:
    """``_row(v)``, once per physically distinct vehicle (``key``: its physics_key, what decides
    how it drives; _row reads nothing else but the id its errors name, and errors are not kept)."""
    try:
        key = v.physics_key() if key is None else key
        row = _ROWS.get(key)
    except TypeError:   # unhashable (e.g. a list where a tuple belongs): not cached
        return _packed(_row(v))
    if row is None:
        row = _packed(_row(v))
        if len(_ROWS) >= ROW_CACHE_SIZE:
            del _ROWS[next(iter(_ROWS))]
        _ROWS[key] = row
    return row


def _packed(row: dict) -> dict:
    """``row`` with its gear combos (n, 4) and its ``_NUMBERS`` as float arrays, converted once
    per row (the same float of each value the whole fleet's conversion in :func:`_gather` gave)."""
    row["combo_array"] = np.array([c[:4] for c in row["combos"]], float).reshape(-1, 4)
    row["number_array"] = np.array(itemgetter(*_NUMBERS)(row), float)
    return row


def _combos(rows: list, K: int) -> np.ndarray:
    """The rows' gear combos as one (V, K, 4) array, padded with ``_NO_COMBO`` beyond each row's own."""
    combos = np.empty((len(rows), K, 4))
    combos[:] = _NO_COMBO
    counts = np.array([len(r["combos"]) for r in rows], np.intp)
    if counts.sum():
        within = np.arange(K) < counts[:, None]          # the rows' own combos, in order
        combos[within] = np.concatenate([r["combo_array"] for r in rows])
    return combos


def _with(defaults, record):
    """``defaults`` (an EngineSet or TransmissionSet) with the fields of ``record`` (a heavy-duty
    record) on top; None: unchanged."""
    return defaults if record is None else replace(defaults, **asdict(record))


def _or(value: float | None, default: float) -> float:
    """A set's value, or ``default`` where the set has none."""
    return default if value is None else value


def _row(v: VehicleSpec) -> dict:
    """One vehicle's checked parameters with defaults filled in."""
    _check(v)
    eng = engine_defaults(v.fuel, v.duty_class)
    box = gearbox_type(v)
    trn = transmission_defaults(box)
    cfg = canonical(v.configuration)
    dual = cfg in DUAL_CONFIGURATIONS
    low = float(v.low_gear_ratio) if dual else 1.0
    T_peak = float(v.peak_engine_torque_Nm)
    n_idle = _get(v, "idle_speed_rpm", eng.idle_speed_rpm)
    n_rated = float(v.rated_speed_rpm) if v.rated_speed_rpm else _get(v, "rated_speed_rpm", eng.rated_speed_rpm)
    n_pk = _get(v, "peak_torque_speed_rpm", eng.peak_torque_speed_fraction * n_rated)
    trn = _with(trn, heavy_duty_shift_speeds(v, n_pk))   # MD/HD diesels: models/heavy_duty/drivelines.toml
    P_rated = (float(v.rated_power_kW) if v.rated_power_kW else
               eng.rated_power_factor * T_peak * n_rated * RAD_S_PER_RPM / 1e3)
    disp = (float(v.engine_displacement_L) if v.engine_displacement_L else
            4 * math.pi * T_peak / (eng.bmep_at_peak_kPa * 1e3) * 1e3)
    eng = _with(eng, heavy_duty_fuel_constants(v, disp, eng.idle_speed_rpm, eng.peak_torque_speed_fraction,
                                               eng.idle_torque_fraction))   # MD/HD diesels: models/heavy_duty/
    cylinders = _get(v, "cylinders", None)
    if cylinders is None:
        cylinders = default_cylinders(disp)
    gears = tuple(float(g) for g in v.transmission_gear_ratios)
    if box == "cvt":  # the variator's range as geometric steps (first guess and full-load table)
        hi, lo = max(gears), min(gears)
        gears = tuple(hi * (lo / hi) ** (i / (CVT_STEPS - 1)) for i in range(CVT_STEPS)) if hi > lo else (hi,)
    g_eff = _get(v, "gear_efficiency", trn.gear_efficiency)
    d_eff = _get(v, "direct_gear_efficiency", _or(trn.direct_gear_efficiency, g_eff))
    combos = []
    for i, g in enumerate(gears):
        eff = d_eff if abs(g - 1.0) < 0.02 and box != "cvt" else g_eff
        combos.append((g, False, i + 1, eff, g))
        if dual:
            combos.append((g, True, i + 1, eff, g * low))
    combos.sort(key=lambda c: -c[4])
    converter = box in ("automatic", "cvt")
    return dict(
        cfg=cfg,
        mass=float(v.test_weight_kg),
        rot=_get(v, "rotating_mass_fraction", ROTATING_MASS_FRACTION.get(v.duty_class, 0.015)),
        coast=(v.coastdown_A_lbf, v.coastdown_B_lbf_per_mph, v.coastdown_C_lbf_per_mph2),   # SI in _gather
        radius=_rolling_radius_m(v.tire_size, _get(v, "tire_rolling_radius_factor", 1.0)),
        fd=float(v.final_drive_ratio), low=low, kim=v.kim_torque_scale_Nm, combos=combos,
        auto=converter, cvt=box == "cvt", cvt_range=(max(gears), min(gears)),
        lockup_clutch=_yes_no(v, "converter_lockup", True),
        spin=(_get(v, "spin_loss_Nm_at_0", trn.spin_loss_Nm_at_0),
              _get(v, "spin_loss_Nm_per_krpm", trn.spin_loss_Nm_per_krpm)),
        stall_TR=_get(v, "stall_torque_ratio", v.converter_ratio if converter else 1.0),
        # a converter that stalls above the engine's torque band could never hold full
        # torque: the default stall speed is at most 3/4 of rated speed
        stall_rpm=_get(v, "stall_speed_rpm", min(_or(trn.stall_speed_rpm, 2000.0), 0.75 * n_rated)),
        lockup=_get(v, "lockup_speed_rpm", _or(trn.lockup_speed_rpm, 0.0)),
        launch=_get(v, "launch_speed_rpm", _or(trn.launch_speed_rpm, n_idle)),
        T_peak=T_peak, P=P_rated, n_rated=n_rated, n_idle=n_idle,
        n_pk=n_pk,
        idle_T=_get(v, "idle_torque_fraction", eng.idle_torque_fraction),
        disp=disp, cylinders=cylinders, bore_stroke=_get(v, "bore_stroke_ratio", 1.0),   # the stroke in _gather
        throttled=v.fuel == "gasoline",
        fuel_constants=(tuple(_get(v, key, getattr(eng, key)) for key in FUEL_CONSTANTS) if v.extra
                        else _fuel_constants_of(eng)),   # no extra column: the set's (none is a field)
        lhv=_get(v, "lhv_MJ_per_kg", eng.lhv_MJ_per_kg),
        rho=_get(v, "density_kg_per_L", eng.density_kg_per_L),
        shift=_get(v, "shift_speed_min_rpm", _or(trn.shift_speed_min_rpm, eng.shift_speed_min_rpm)),
        shift_accel=_get(v, "shift_speed_accel_rpm", _or(trn.shift_speed_accel_rpm, 0.0)),
        reserve=_get(v, "power_reserve", eng.power_reserve),
        cut=_get(v, "fuel_cut_speed_rpm", eng.fuel_cut_speed_rpm),
        idle_fuel=_get(v, "idle_fuel_g_per_s", float("nan")),
        fuel=v.fuel,
        technology=_technology(v),
    )


def _technology(v: VehicleSpec) -> tuple[bool, ...]:
    """The ``technology`` column as flags (simulation/technology.py); errors name the vehicle."""
    text = column_value(v, "technology")
    try:
        return _technology_flags(text) if type(text) is str else parse_technology(text)
    except FleetrunError as exc:
        raise InputError(f"vehicle '{v.vehicle_id}': {exc.message}", column="technology",
                         value=column_value(v, "technology"), hint=exc.hint) from None


_technology_flags = lru_cache(maxsize=256)(parse_technology)   # a technology text, parsed once


def _rolling_radius_m(tire_size, factor: float) -> float:
    """tyre.rolling_radius_m, once per (size, factor) text in a process."""
    return _radius_of_size(tire_size, factor) if type(tire_size) is str else rolling_radius_m(tire_size, factor)


_radius_of_size = lru_cache(maxsize=4096)(rolling_radius_m)

_NUMBERS = ("mass", "rot", "radius", "fd", "low", "kim", "stall_TR", "stall_rpm", "lockup", "launch", "T_peak", "P",
            "n_rated", "n_idle", "n_pk", "idle_T", "disp", "cylinders", "bore_stroke", "lhv", "rho", "shift",
            "shift_accel", "reserve", "cut", "idle_fuel")
_NO_COMBO = (0.0, False, 1, 1.0)   # padding beyond a vehicle's combos: ratio 0, high range, gear 1, efficiency 1


def _gather(rows: list) -> VehicleArrays:
    V = len(rows)
    K = max((len(r["combos"]) for r in rows), default=1)
    # one conversion per kind of value (not one per value): (V, K, 4) combos, (V, numbers)
    combos = _combos(rows, K)
    ctr, clow = np.ascontiguousarray(combos[:, :, 0]), combos[:, :, 1] != 0
    cg, ceff = combos[:, :, 2].astype(np.int16), np.ascontiguousarray(combos[:, :, 3])
    numbers = np.array([r["number_array"] for r in rows], float).reshape(V, len(_NUMBERS))
    columns = dict(zip(_NUMBERS, np.ascontiguousarray(numbers.T)))
    a = columns.__getitem__
    # per vehicle as in the row, the conversions once over the arrays (the same operations element by element)
    coast = np.array(coastdown_to_si(*np.array([r["coast"] for r in rows], float).reshape(V, 3).T)).T
    T_peak = a("T_peak")
    return VehicleArrays(
        n=V, configuration=[r["cfg"] for r in rows], mass_kg=a("mass"), rot_frac=a("rot"),
        A_N=coast[:, 0], B_N=coast[:, 1], C_N=coast[:, 2], radius_m=a("radius"),
        final_drive=a("fd"), low_ratio=a("low"), kim_torque_scale_Nm=a("kim"),
        combo_trans_ratio=ctr, combo_axle_low=clow, combo_gear=cg, combo_gear_eff=ceff,
        n_combos=np.array([len(r["combos"]) for r in rows]),
        automatic=np.array([r["auto"] for r in rows], bool), cvt=np.array([r["cvt"] for r in rows], bool),
        cvt_ratio_range=np.array([r["cvt_range"] for r in rows], float).reshape(V, 2),
        has_lockup=np.array([r["lockup_clutch"] for r in rows], bool),
        spin_loss=np.array([r["spin"] for r in rows], float).reshape(V, 2), stall_TR=a("stall_TR"),
        K_tc=a("stall_rpm") / np.sqrt(T_peak), lockup_rpm=a("lockup"), launch_rpm=a("launch"),
        T_peak=T_peak, P_rated_kW=a("P"), n_rated=a("n_rated"), n_idle=a("n_idle"),
        n_peak_torque=a("n_pk"), idle_T_frac=a("idle_T"), displacement_L=a("disp"),
        stroke_m=stroke_m(a("disp"), a("cylinders"), a("bore_stroke")), throttled=np.array([r["throttled"] for r in rows], bool),
        fuel_constants=np.array([r["fuel_constants"] for r in rows], float).reshape(V, len(FUEL_CONSTANTS)),
        lhv=a("lhv"), density=a("rho"), shift_min_rpm=a("shift"), shift_accel_rpm=a("shift_accel"), power_reserve=a("reserve"),
        fuel_cut_rpm=a("cut"), idle_fuel_g_s=a("idle_fuel"), fuel=[r["fuel"] for r in rows],
        technology=np.array([r["technology"] for r in rows], bool).reshape(V, len(TECHNOLOGIES)),
    )


def refused_vehicles(vehicles: Sequence[VehicleSpec]) -> list[tuple[int, FleetrunError]]:
    """(index, error) of each vehicle whose parameters the simulation refuses: what
    :func:`vehicle_arrays` would raise for it. Physically equal rows are checked once, so the
    workbook reader can run this on every row (``fleetrun validate`` catches what ``run`` refuses).

    Parameters
    ----------
    vehicles : sequence of VehicleSpec, the Vehicles rows

    Returns
    -------
    list of (int, FleetrunError), the index and error of each refused row (electric rows skipped).
    """
    verdicts: dict = {}
    refused = []
    unseen = object()
    for i, v in enumerate(vehicles):
        if v.fuel == "electric":  # battery-electric rows run on fleetrun.simulation.electric, not these
            continue
        key = v.physics_key()
        verdict = verdicts.get(key, unseen)
        if verdict is unseen:
            try:
                _row_cached(v, key)
                verdict = None
            except FleetrunError as exc:
                verdict = exc
            verdicts[key] = verdict
        if verdict is not None:
            refused.append((i, verdict))
    return refused
