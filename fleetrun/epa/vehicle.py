"""One Vehicles row from a configuration's facts, and the record of what was derived.

Taken from the list (unit conversions only): test weight, road-load coefficients, axle
ratio, N/V, rated power, displacement, cylinders, converter lock-up, transmission and drive
codes. Derived by :mod:`fleetrun.epa.rules`: peak torque, tyre size, gear ratios (or the
CVT's ratio range), vehicle class, and the defaults for count and annual miles.
"""
from __future__ import annotations

from fleetrun.epa import rules
from fleetrun.simulation.tyre import rolling_radius_m

RATIO_DIGITS = 4


def _ratio_text(ratios) -> str:
    return ",".join(f"{r:.{RATIO_DIGITS}f}" for r in ratios)


def vehicle_row(vehicle_id: str, f: dict) -> tuple[dict, list[dict]]:
    """The Vehicles row (workbook column -> value) and the derivations (vehicle_id, column,
    value, rule) of the configuration whose facts are ``f``."""
    c = rules.constants()
    units, defaults = c["units"], c["defaults"]
    gearbox, transmission = c["transmissions"][f["transmission_code"]]
    configuration = c["drives"][f["drive_code"]]
    derived: list[dict] = []

    def note(column, value, rule):
        derived.append({"vehicle_id": vehicle_id, "column": column, "value": value, "rule": rule})

    power_kW = float(f["rated_hp"]) * units["hp_to_kW"]
    weight_kg = float(f["test_weight_lb"]) * units["lb_to_kg"]
    torque, bmep = rules.peak_torque_Nm(power_kW, float(f["displacement_L"]), diesel=f["fuel"] == "diesel")
    note("peak_engine_torque_Nm", round(torque, 1),
         f"peak BMEP {bmep:.2f} bar (specific power {power_kW / f['displacement_L']:.1f} kW/L) x "
         f"{f['displacement_L']:g} L / (4 pi) [Heywood 1988 Eq. 2.19; models/epa_import.toml [torque]]")
    tyre = rules.tyre_size_for_weight(float(f["test_weight_lb"]))
    radius = rolling_radius_m(tyre)
    note("tire_size", tyre, f"common size for an equivalent test weight of {f['test_weight_lb']:g} lb "
                            f"(radius {radius:.4f} m) [models/epa_import.toml [[tyres]]]")
    ratios = _gear_ratios(f, gearbox, radius, note)
    vehicle_type = c["vehicle_type"].get(f.get("vehicle_type") or "", "vehicle")
    drive = configuration.removeprefix("LD_")
    note("vehicle_class", f"{vehicle_type} {drive}", "Vehicle Type and drive system")
    note("annual_miles", defaults["annual_miles"], "default [models/epa_import.toml [defaults]]")
    note("rated_power_kW", round(power_kW, 3), f"Rated Horsepower {f['rated_hp']:g} hp x {units['hp_to_kW']}")
    note("test_weight_kg", round(weight_kg, 3),
         f"Equivalent Test Weight {f['test_weight_lb']:g} lb x {units['lb_to_kg']}")
    row = {
        "vehicle_id": vehicle_id, "vehicle_class": f"{vehicle_type} {drive}", "duty_class": defaults["duty_class"],
        "configuration": configuration, "count": defaults["count"], "annual_miles": defaults["annual_miles"],
        "fuel": f["fuel"], "peak_engine_torque_Nm": round(torque, 1), "transmission": transmission,
        "transmission_gear_ratios": _ratio_text(ratios), "final_drive_ratio": float(f["axle_ratio"]),
        "test_weight_kg": round(weight_kg, 3), "coastdown_A_lbf": float(f["coef_A_lbf"]),
        "coastdown_B_lbf_per_mph": float(f["coef_B_lbf_per_mph"]),
        "coastdown_C_lbf_per_mph2": float(f["coef_C_lbf_per_mph2"]), "tire_size": tyre,
        "rated_power_kW": round(power_kW, 3), "engine_displacement_L": float(f["displacement_L"]),
        "manufacturer": f["manufacturer"], "make": f["make"], "model": f["model"],
        "model_year": None if f["model_year"] is None else int(f["model_year"]),
        "gearbox_type": gearbox, "converter_lockup": _lockup(f.get("lockup", "")),
        "cylinders": None if f.get("cylinders") is None else int(f["cylinders"]),
        "nv_ratio_rpm_per_mph": float(f["nv_ratio"]),
    }
    return row, derived


def _gear_ratios(f: dict, gearbox: str, radius_m: float, note) -> list[float]:
    axle, nv = float(f["axle_ratio"]), float(f["nv_ratio"])
    if gearbox == "cvt":
        base, what = rules.cvt_ratio_set(), "generic CVT ratio range (models/epa_import.toml [cvt])"
    else:
        base, source = rules.generic_gear_set(int(f["gears"]))
        what = f"generic {int(f['gears'])}-speed set ({source}; models/epa_import.toml [gears])"
    ratios, scale = rules.scale_to_nv(base, axle, nv, radius_m)
    note("transmission_gear_ratios", _ratio_text(ratios),
         f"{what} x {scale:.4f}, so that top gear x axle {axle:g} with the tyre's {radius_m:.4f} m radius "
         f"turns the engine at the list's N/V {nv:g} rpm/mph")
    return ratios


def _lockup(value) -> str | None:
    text = str(value or "").strip().upper()
    return {"Y": "yes", "N": "no"}.get(text)
