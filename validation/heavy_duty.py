"""Heavy-duty validation (docs/validation-heavy-duty.md).

    python validation/heavy_duty.py [--write] [--plot docs/img/validation-heavy-duty.png]

Run from the checkout root (``PYTHONPATH=$PWD``). Three checks, each against a published figure:

1. the issue's typed class-8 tractor (65,000 lb, CdA 5.8 m^2, Crr 6.5 kg/t, 15 L 2,237 N m,
   18-speed manual, axle 2.64, 295/75R22.5) at a level 65 and 55 mph: mpg against the
   6.5-7.5 / 7.8-9.0 mpg that its road load, a 0.93 driveline and a 43-45 % brake efficiency
   give (issue 21);
2. the Phase 2 reference vehicles of ``models/heavy_duty/gem_reference_vehicles.toml`` on GEM's
   cycles and weighting, vocational vehicles with GEM's drive- and parked-idle cycles:
   g CO2/ton-mile against the standard each is set at (40 CFR 1037.105, 1037.106); and again
   with DOE's MY2020 road-load inputs as NREL T3CO ships them, where T3CO has the class
   (``models/heavy_duty/reference_inputs_doe_nrel.toml``, a sensitivity), and the tractors with
   their CdA read as measured and run at its GEM bin's input (1037.520(b)(3), a sensitivity);
3. the example fleet's combination trucks over their scenarios' heavy-duty cycle mixes (the
   national VM-1 2010 split of combination-truck miles over road categories,
   inputs/state_statistics/vm1_truck_travel.toml): mpg against the national combination-truck
   range (FHWA Highway Statistics VM-1, 5.4-6.4 mpg), and how it moves with the road -> cycle
   rule and with the on-road (weigh-in-motion) weight.

``--write`` stores the relative fuel-economy errors of check 2 as
``models/heavy_duty/fuel_economy_error.toml`` (the shape of models/fuel_economy_error.toml).
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import sys
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetrun.resources import models_dir  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.physics.fuels import fuel_properties  # noqa: E402
from fleetrun.simulation.heavy_duty_gem import (composite_g_co2_per_ton_mile, gem_cycle_mix,  # noqa: E402
                                                idle_fuel_rates_g_per_s, idle_gallons_per_mile, idle_shares,
                                                payload_short_tons)
from fleetrun.simulation.params import vehicle_arrays  # noqa: E402
from fleetrun.units import LITERS_PER_GALLON  # noqa: E402
from fleetrun.simulation.heavy_duty_road_load import gem_cda_input_m2, gem_coastdown_lbf  # noqa: E402
from fleetrun.workbook import read_fleet  # noqa: E402
from fleetrun.cycles import DriveCycle, load_cycle  # noqa: E402
from fleetrun.resources import model_file  # noqa: E402
from fleetrun.simulation.heavy_duty_engine import (heavy_duty_constants, reference_engine,  # noqa: E402
                                                   service_class, set_co2_g_per_hp_hr, set_ramped_co2_g_per_hp_hr,
                                                   standard_for)
from fleetrun.workbook.vehicle_file import vehicle_from_mapping  # noqa: E402

LB_KG = 0.45359237
HD_DIR = models_dir() / "heavy_duty"
ERROR_FILE = HD_DIR / "fuel_economy_error.toml"
TYPED_TRACTOR = dict(
    vehicle_id="TYPED-CLASS8", vehicle_class="Class 8 tractor", count=1, annual_miles=1, duty_class="HD",
    configuration="HD_TANDEM", fuel="diesel", peak_engine_torque_Nm=2237.0, transmission="manual",
    transmission_gear_ratios="14.40,12.29,8.56,7.30,6.05,5.16,4.38,3.74,3.20,2.73,2.29,1.95,1.62,1.38,1.17,1.00,0.86,0.73",
    final_drive_ratio=2.64, tire_size="295/75R22.5", engine_displacement_L=15.0)
TYPED_WEIGHT_LB, TYPED_CRR, TYPED_CDA = 65000.0, 0.0065, 5.8
TYPED_TARGETS_MPG = {"CRUISE-65": (6.5, 7.5), "CRUISE-55": (7.8, 9.0)}
VM1_COMBINATION_MPG = (5.4, 6.4)
COMBINATION_CLASS = "Tractor-trailer (class 8)"


def gem_row(basis: dict, vehicle_id: str) -> dict:
    """A Vehicles row (mapping) from GEM inputs: weight [lb], Crr [kg/t], CdA [m^2]."""
    mass = basis["test_weight_lb"] * LB_KG
    a, b, c = gem_coastdown_lbf(mass, basis["crr_kg_per_t"] / 1000.0, basis["cda_m2"])
    skip = {"gem_type", "regulatory_class", "standard_g_per_ton_mile", "test_weight_lb", "crr_kg_per_t", "cda_m2",
            "road_load_source"}
    row = {k: v for k, v in basis.items() if k not in skip}
    return dict(row, vehicle_id=vehicle_id, vehicle_class=vehicle_id, count=1, annual_miles=1, test_weight_kg=mass,
                coastdown_A_lbf=float(a), coastdown_B_lbf_per_mph=float(b), coastdown_C_lbf_per_mph2=float(c))


def typed_tractor():
    row = gem_row(dict(TYPED_TRACTOR, test_weight_lb=TYPED_WEIGHT_LB, crr_kg_per_t=TYPED_CRR * 1000,
                       cda_m2=TYPED_CDA), "TYPED-CLASS8")
    return vehicle_from_mapping(row, Path("typed-tractor"))


def check_typed_tractor() -> list[dict]:
    v = typed_tractor()
    rows = []
    for cycle, (low, high) in TYPED_TARGETS_MPG.items():
        r = simulate([v], cycle)
        mpg = float(r.mpg[0])
        rows.append(dict(cycle=cycle, mpg=round(mpg, 3), target_low=low, target_high=high,
                         drivetrain_efficiency=round(float(r.drivetrain_efficiency[0]), 4),
                         brake_efficiency=round(brake_efficiency(r), 4), within=bool(low <= mpg <= high)))
    return rows


def brake_efficiency(result) -> float:
    """Engine work / fuel energy over the cycle (diesel LHV, models/fuels.toml)."""
    from fleetrun.physics.fuels import fuel_properties

    return float(result.engine_energy_J[0] / (result.fuel_g[0] * fuel_properties("diesel").lhv_MJ_per_kg * 1e3))


def reference_vehicles() -> tuple[dict, dict]:
    """(defaults, {name: inputs}) of gem_reference_vehicles.toml; a vehicle whose CdA and Crr
    are owned by another file (``road_load_source``, e.g. ``reference_inputs_doe_nrel``) gets
    them from it."""
    with open(HD_DIR / "gem_reference_vehicles.toml", "rb") as fh:
        data = tomllib.load(fh)
    sources = {"reference_inputs_doe_nrel": doe_nrel_road_load}
    vehicles = {}
    for name, basis in data["vehicles"].items():
        source = basis.get("road_load_source")
        vehicles[name] = dict(basis, **sources[source]()[name]) if source else basis
    return data["defaults"], vehicles


def doe_nrel_road_load() -> dict[str, dict]:
    """{reference vehicle: {cda_m2, crr_kg_per_t}} of DOE's MY2020 no-program vehicles as NREL
    T3CO ships them (models/heavy_duty/reference_inputs_doe_nrel.toml; only the vehicles T3CO
    has a class for)."""
    with open(HD_DIR / "reference_inputs_doe_nrel.toml", "rb") as fh:
        data = tomllib.load(fh)
    return {name: dict(cda_m2=v["drag_coef"] * v["frontal_area_m2"], crr_kg_per_t=v["wheel_rr_coef"] * 1000.0)
            for name, v in data["vehicles"].items()}


def idle_gallons_per_hour(specs: list) -> tuple[np.ndarray, np.ndarray]:
    """(drive idle, parked idle) fuel [gal/h] of each vehicle (heavy_duty_gem)."""
    g_per_gal = fuel_properties("diesel").density_kg_per_L * LITERS_PER_GALLON * 1e3
    drive, parked = idle_fuel_rates_g_per_s(vehicle_arrays(specs))
    return drive * 3600.0 / g_per_gal, parked * 3600.0 / g_per_gal


# GEM's aerodynamic bin tables per reference tractor (gem_aero_bins.toml keys)
TRACTOR_AERO_TYPES = {"class8_sleeper_high_roof": "high_roof_sleeper_cab", "class8_day_high_roof": "high_roof_day_cab",
                      "class7_day_high_roof": "high_roof_day_cab"}


def gem_bin_road_load() -> dict[str, dict]:
    """{reference tractor: {cda_m2, crr_kg_per_t}} with the reference CdA read as a measured
    drag area and replaced by its bin's GEM input (40 CFR 1037.520(b)(3), model year of the
    standard)."""
    defaults, vehicles = reference_vehicles()
    return {name: dict(cda_m2=gem_cda_input_m2(kind, vehicles[name]["cda_m2"], defaults["standard_year"]),
                       crr_kg_per_t=vehicles[name]["crr_kg_per_t"]) for name, kind in TRACTOR_AERO_TYPES.items()}


def check_reference_vehicles(with_idle: bool = True, road_load: dict | None = None, columns: dict | None = None,
                             idle_add_gal_per_h: dict | None = None, stops_in_drive: bool = False) -> list[dict]:
    """Each reference vehicle's GEM composite against its standard; ``with_idle=False``:
    without the vocational idle cycles (as before 2026-11-25); ``road_load``: {vehicle:
    {cda_m2, crr_kg_per_t}} in place of the reference file's (only those vehicles are run);
    ``columns``: {vehicle: {Vehicles column: value}} added to its row (e.g. accessory_power_W;
    only those vehicles are run); ``idle_add_gal_per_h``: {vehicle: gal/h} added to its drive-
    and parked-idle fuel rates; ``stops_in_drive``: the drive cycles' stops burn the drive-idle
    rate (an automatic held in gear) instead of the simulation's no-load idle (sensitivities,
    docs/validation-heavy-duty.md)."""
    defaults, vehicles = reference_vehicles()
    if road_load is not None:
        vehicles = {name: dict(vehicles[name], **inputs) for name, inputs in road_load.items()}
    if columns is not None:
        vehicles = {name: dict(vehicles[name], **extra) for name, extra in columns.items()}
    specs = {name: vehicle_from_mapping(gem_row(dict(basis, fuel=defaults["fuel"],
                                                     engine_model_year=defaults["standard_year"]), name), Path(name))
             for name, basis in vehicles.items()}
    cycles = sorted({c for b in vehicles.values() for c in gem_cycle_mix(b["gem_type"])})
    gal_per_mile = {}
    for cycle in cycles:
        r = simulate(list(specs.values()), cycle)
        for i, name in enumerate(specs):
            gal_per_mile.setdefault(name, {})[cycle] = float(r.fuel_gal[i] / r.miles[i])
    drive_gph, parked_gph = idle_gallons_per_hour(list(specs.values()))
    added = np.array([(idle_add_gal_per_h or {}).get(name, 0.0) for name in specs])
    if stops_in_drive:   # the stops burn the (added-to) drive idle instead of the simulation's no-load idle
        _stops_in_drive(gal_per_mile, dict(zip(specs, drive_gph + added - parked_gph)))
    drive_gph, parked_gph = drive_gph + added, parked_gph + added
    rows = []
    for i, (name, basis) in enumerate(vehicles.items()):
        mix = gem_cycle_mix(basis["gem_type"])
        drive, parked, speed = idle_shares(basis["gem_type"])
        idle = float(idle_gallons_per_mile(drive_gph[i], parked_gph[i], drive, parked, speed)) if with_idle else 0.0
        payload = payload_short_tons(basis["regulatory_class"])
        model = composite_g_co2_per_ton_mile(gal_per_mile[name], mix, payload, idle_gal_per_mile=idle)
        standard = basis["standard_g_per_ton_mile"]
        rows.append(dict(vehicle=name, gem_type=basis["gem_type"], standard_year=defaults["standard_year"],
                         model_g_per_ton_mile=round(model, 2), standard_g_per_ton_mile=standard,
                         idle_g_per_ton_mile=round(composite_g_co2_per_ton_mile({}, {}, payload,
                                                                                  idle_gal_per_mile=idle), 2),
                         drive_idle_gal_per_h=round(float(drive_gph[i]), 3),
                         parked_idle_gal_per_h=round(float(parked_gph[i]), 3),
                         mpg_by_cycle={c: round(1.0 / g, 3) for c, g in gal_per_mile[name].items()},
                         co2_error=round(model / standard - 1.0, 4),
                         mpg_error=round(standard / model - 1.0, 4)))
    return rows


def stopped_hours_per_mile(cycle_name: str) -> float:
    """Hours the schedule of ``cycle_name`` stands still (speed 0 at both ends of a step) per
    mile it covers."""
    c = load_cycle(cycle_name)
    still = (c.speed_mps[1:] < 0.01) & (c.speed_mps[:-1] < 0.01)
    miles = float(np.trapezoid(c.speed_mps, c.time_s)) / 1609.344
    return float(np.diff(c.time_s)[still].sum()) / 3600.0 / miles


def _stops_in_drive(gal_per_mile: dict, extra_gal_per_h: dict) -> None:
    """Add, in place, each vehicle's drive-minus-parked idle rate [gal/h] over the stops of each
    cycle to its gallons per mile: GEM simulates an automatic stopped in the transient cycle in
    gear (neutral idle is an improvement input, 40 CFR 1037.520(h)(2)(ii)), fleetrun's
    simulation idles it with no load."""
    for name, cycles in gal_per_mile.items():
        for cycle in cycles:
            cycles[cycle] = float(cycles[cycle] + extra_gal_per_h[name] * stopped_hours_per_mile(cycle))


# ------------------------------------------------------------ where the class 8 tractors' gap comes from
LEVEL_CRUISE = {"CRUISE-55-GRADE": "CRUISE-55", "CRUISE-65-GRADE": "CRUISE-65"}


def grade_by_distance(cycle: DriveCycle, achieved_mps) -> DriveCycle:
    """``cycle`` with its grade read at the distance the vehicle has driven instead of the
    distance the schedule has: Appendix IV to part 1037 gives GEM's grade as a function of
    distance, while a shipped cycle carries it per time stamp (both agree while the vehicle
    holds the set speed; a loaded tractor falls behind on the 5 % climbs)."""
    t, v = cycle.time_s, cycle.speed_mps
    x_schedule = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    a = np.asarray(achieved_mps, float)
    x_driven = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
    return DriveCycle(name=cycle.name + "-BY-DISTANCE", time_s=t, speed_mps=v,
                      grade_pct=np.interp(x_driven, x_schedule, cycle.grade_pct))


def _cycle_run(spec, cycle_name: str, variant: str):
    """One vehicle on one cycle; ``variant`` ``distance`` re-reads the grade at the distance
    driven until it settles (four passes; the fuel moves by less than 1e-4 after the third)."""
    if variant == "level":
        return simulate([spec], LEVEL_CRUISE.get(cycle_name, cycle_name))
    r = simulate([spec], cycle_name, trace=variant == "distance")
    if variant == "distance" and cycle_name in LEVEL_CRUISE:
        shipped = load_cycle(cycle_name)
        for _ in range(4):
            r = simulate([spec], grade_by_distance(shipped, r.trace.vehicle_speed_mps[0]), trace=True)
    return r


def tractor_composite(name: str, variant: str = "shipped", **inputs) -> dict:
    """One reference tractor's GEM composite with the reference file's inputs changed by
    ``inputs``, and where its energy goes: composite positive wheel work, engine work and fuel
    per mile (GEM's distance weights), per-cycle drivetrain / differential / engine brake
    efficiency. ``variant``: ``shipped`` (graded cycles as shipped), ``level`` (level cruise),
    ``distance`` (grade read at the distance driven, :func:`grade_by_distance`)."""
    defaults, vehicles = reference_vehicles()
    basis = dict(vehicles[name], **inputs)
    spec = vehicle_from_mapping(gem_row(dict(basis, fuel=defaults["fuel"], engine_model_year=defaults["standard_year"]),
                                        name), Path(name))
    mix, lhv_J_per_g = gem_cycle_mix(basis["gem_type"]), fuel_properties("diesel").lhv_MJ_per_kg * 1e3
    gal, sums, per_cycle = {}, np.zeros(3), {}
    for cycle, share in mix.items():
        r = _cycle_run(spec, cycle, variant)
        gal[cycle] = float(r.fuel_gal[0] / r.miles[0])
        sums += share * np.array([r.wheel_energy_J[0], r.engine_energy_J[0], r.fuel_g[0]], float) / float(r.miles[0])
        per_cycle[cycle] = dict(drivetrain=round(float(r.drivetrain_efficiency[0]), 4),
                                differential=round(float(r.diff_efficiency[0]), 4),
                                engine=round(float(r.engine_energy_J[0] / (r.fuel_g[0] * lhv_J_per_g)), 4))
    payload = payload_short_tons(basis["regulatory_class"])
    model = composite_g_co2_per_ton_mile(gal, mix, payload)
    standard_fuel_g = basis["standard_g_per_ton_mile"] * payload * sums[2] / (model * payload)
    return dict(g_per_ton_mile=round(model, 2), co2_error=round(model / basis["standard_g_per_ton_mile"] - 1.0, 4),
                wheel_kWh_per_mile=round(sums[0] / 3.6e6, 4), engine_kWh_per_mile=round(sums[1] / 3.6e6, 4),
                wheel_to_fuel=round(sums[0] / (sums[2] * lhv_J_per_g), 4),
                wheel_to_fuel_at_standard=round(sums[0] / (standard_fuel_g * lhv_J_per_g), 4), per_cycle=per_cycle)


TRACTOR_VARIANTS = {
    "shipped": ("shipped", {}),
    "level cruise (no grade)": ("level", {}),
    "grade at the distance driven (Appendix IV by distance)": ("distance", {}),
    "single drive axle (HD_RWD; GEM 4x2 / 6x2, 1037.520(g)(2))": ("shipped", {"configuration": "HD_RWD"}),
    "automated manual gearbox (GEM's basis, 1036.540(c)(2), 1037.520(g)(1))":
        ("shipped", {"gearbox_type": "automated_manual"}),
}


def check_tractor_gap() -> list[dict]:
    """The reference tractors under each variant of :data:`TRACTOR_VARIANTS` (one input or
    rule changed at a time against the shipped run), with where the energy goes."""
    _, vehicles = reference_vehicles()
    rows = []
    for name in TRACTOR_AERO_TYPES:
        for label, (variant, inputs) in TRACTOR_VARIANTS.items():
            rows.append(dict(vehicle=name, variant=label, standard_g_per_ton_mile=vehicles[name]["standard_g_per_ton_mile"],
                             **tractor_composite(name, variant, **inputs)))
    return rows


def check_engine_ramped_set() -> list[dict]:
    """Each service class's MY2021 reference engine over the ramped-modal SET (1036.510)
    against its standard (1036.108): the engine side of the tractor gap."""
    hd = model_file("engines.toml")["diesel"]["HD"]
    shape = (hd["idle_speed_rpm"], hd["peak_torque_speed_fraction"], hd["idle_torque_fraction"])
    rows = []
    for service in ("heavy", "medium"):
        engine, constants = reference_engine(service, *shape), heavy_duty_constants(service, 2021, *shape)
        co2, standard = set_ramped_co2_g_per_hp_hr(constants, engine), standard_for(service, 2021)
        rows.append(dict(service=service, model_year=2021, ramped_set_g_per_hp_hr=round(co2, 2),
                         modal_set_g_per_hp_hr=round(set_co2_g_per_hp_hr(constants, engine), 2),
                         standard_g_per_hp_hr=standard, error=round(co2 / standard - 1.0, 5)))
    return rows


def _mix_gal_per_mile(trucks, mix: dict[str, float], ambient_temp_C: float = 20.0) -> np.ndarray:
    """Gallons per mile of each truck over a cycle mix (shares of miles)."""
    gal_per_mile = np.zeros(len(trucks))
    for cycle, share in mix.items():
        r = simulate(trucks, cycle, ambient_temp_C=ambient_temp_C)
        gal_per_mile += share * r.fuel_gal / r.miles
    return gal_per_mile


def _class_mpg(trucks, gal_per_mile) -> float:
    """The trucks' average mpg as a class: their miles over their gallons."""
    miles = np.array([v.count * v.annual_miles for v in trucks], float)
    return float(miles.sum() / (miles * gal_per_mile).sum())


def check_example_combination_trucks(doe_accessories: bool = False) -> list[dict]:
    """The example's combination trucks on their scenarios' heavy-duty mixes, each truck and
    the class average (miles over gallons); ``doe_accessories``: with DOE's accessory load of
    their service class (:func:`doe_accessory_power_W`, a sensitivity)."""
    fleet = read_fleet(ROOT / "inputs" / "example_fleet.xlsx")
    trucks = [v for v in fleet.vehicles if v.vehicle_class == COMBINATION_CLASS]
    if doe_accessories:
        trucks = [dataclasses.replace(v, extra={**(v.extra or {}), "accessory_power_W": doe_accessory_power_W(
            None, v.engine_displacement_L)}) for v in trucks]
    rows = []
    for scenario in fleet.scenarios:
        gal_per_mile = _mix_gal_per_mile(trucks, scenario.mix_for("HD"), scenario.ambient_temp_C)
        mpgs = [(v.vehicle_id, float(1.0 / g)) for v, g in zip(trucks, gal_per_mile)]
        for vid, mpg in mpgs + [("class average", _class_mpg(trucks, gal_per_mile))]:
            rows.append(dict(scenario=scenario.scenario_id, vehicle=vid, mpg=round(mpg, 3),
                             within_vm1=bool(VM1_COMBINATION_MPG[0] <= mpg <= VM1_COMBINATION_MPG[1])))
    return rows


# Other readings of VM-1's road categories, for the sensitivity of the example's mix
# (docs/validation-heavy-duty.md): the arterials on GEM's urban transient, and every
# non-Interstate mile on the HD-UDDS (the registrations default before 2026-11).
VM1_RULE_VARIANTS = {
    "rural other arterials on ARB-TRANSIENT": {"rural_other_arterial": "ARB-TRANSIENT"},
    "all non-Interstate on HD-UDDS": {"rural_other_arterial": "HD-UDDS", "rural_other": "HD-UDDS",
                                      "urban_other": "HD-UDDS"},
}


def _vm1_mix(data: dict, rule: dict) -> dict[str, float]:
    miles = data["vehicle_miles_million"]["combination_trucks"]
    mix: dict[str, float] = {}
    for road, cycle in rule.items():
        mix[cycle] = mix.get(cycle, 0.0) + miles[road] / sum(miles.values())
    return mix


def check_example_mix_sensitivity() -> list[dict]:
    """The example's combination trucks (20 C) on the VM-1 mix under the shipped road -> cycle
    rule and its variants, at their workbook weights and at the mean weigh-in-motion weight of
    five-axle tractor-trailers (road load A and B scaled with the mass)."""
    with open(ROOT / "inputs" / "state_statistics" / "vm1_truck_travel.toml", "rb") as fh:
        data = tomllib.load(fh)
    wim = data["tractor_trailer_weigh_in_motion_2008"]
    mean_lb = float(np.average(wim["weight_lb"], weights=wim["trucks"]))
    trucks = [v for v in read_fleet(ROOT / "inputs" / "example_fleet.xlsx").vehicles
              if v.vehicle_class == COMBINATION_CLASS]
    light = [dataclasses.replace(v, test_weight_kg=mean_lb * LB_KG,
                                 coastdown_A_lbf=v.coastdown_A_lbf * mean_lb * LB_KG / v.test_weight_kg,
                                 coastdown_B_lbf_per_mph=v.coastdown_B_lbf_per_mph * mean_lb * LB_KG / v.test_weight_kg)
             for v in trucks]
    rules = {"shipped": data["cycle_for_road"]}
    rules.update({name: {**data["cycle_for_road"], **change} for name, change in VM1_RULE_VARIANTS.items()})
    rows = []
    for name, rule in rules.items():
        mix = _vm1_mix(data, rule)
        for weight, fleet_rows in (("workbook", trucks), (f"WIM mean {mean_lb:.0f} lb", light)):
            g = _mix_gal_per_mile(fleet_rows, mix)
            rows.append(dict(rule=name, weight=weight, mix={c: round(s, 4) for c, s in mix.items()},
                             mpg={v.vehicle_id: round(float(1.0 / x), 3) for v, x in zip(trucks, g)},
                             class_mpg=round(_class_mpg(trucks, g), 3)))
    return rows


def check_example_trucks_on_gem_weighting() -> list[dict]:
    """The example fleet's combination trucks (as typed, fully loaded) on GEM's day- and
    sleeper-cab weighting of the heavy-duty cycles."""
    fleet = read_fleet(ROOT / "inputs" / "example_fleet.xlsx")
    trucks = [v for v in fleet.vehicles if v.vehicle_class == COMBINATION_CLASS]
    rows = []
    for gem_type in ("day_cab", "sleeper_cab"):
        gal_per_mile = np.zeros(len(trucks))
        for cycle, share in gem_cycle_mix(gem_type).items():
            r = simulate(trucks, cycle)
            gal_per_mile += share * r.fuel_gal / r.miles
        rows += [dict(gem_type=gem_type, vehicle=v.vehicle_id, mpg=round(float(1.0 / g), 3),
                      within_vm1=bool(VM1_COMBINATION_MPG[0] <= 1.0 / g <= VM1_COMBINATION_MPG[1]))
                 for v, g in zip(trucks, gal_per_mile)]
    return rows


FHWA_GEM_TYPES = {"combination_truck": ("day_cab", "sleeper_cab"),
                  "single_unit_truck": ("vocational_regional", "vocational_multipurpose"),
                  "bus": ("vocational_multipurpose", "vocational_urban")}


def check_fhwa_class_defaults() -> list[dict]:
    """mpg of the FHWA class defaults (models/heavy_duty/fhwa_classes.toml) on GEM weightings."""
    with open(HD_DIR / "fhwa_classes.toml", "rb") as fh:
        classes = tomllib.load(fh)
    rows = []
    for name, gem_types in FHWA_GEM_TYPES.items():
        row = {k: v for k, v in classes[name].items() if k != "source"}
        spec = vehicle_from_mapping(dict(row, vehicle_id=name, vehicle_class=name, count=1), Path(name))
        for gem_type in gem_types:
            gal = sum(share * float(r.fuel_gal[0] / r.miles[0])
                      for cycle, share in gem_cycle_mix(gem_type).items() for r in [simulate([spec], cycle)])
            rows.append(dict(fhwa_class=name, gem_type=gem_type, mpg=round(1.0 / gal, 3)))
    return rows


def measured_idle() -> dict[str, dict]:
    """The measured no-load idle fuel of diesel trucks (models/heavy_duty/idle_fuel_measured.toml,
    DOE VTO Fact #861) and the reference vehicles each is compared with."""
    with open(HD_DIR / "idle_fuel_measured.toml", "rb") as fh:
        return tomllib.load(fh)["trucks"]


def model_no_load_idle_gal_per_h(accessories: str = "none") -> dict[str, float]:
    """{reference vehicle: its engine's idle fuel [gal/h] at idle speed and no load}: the
    light-load end of the fuel map, as Fact #861 measured trucks. ``accessories``: ``none``
    (the engine alone), ``default`` (the simulation's own heavy-diesel accessory load,
    engines.toml) or ``doe`` (DOE's, :func:`doe_accessory_power_W`)."""
    defaults, vehicles = reference_vehicles()
    load = {"none": lambda name, b: {"accessory_power_W": 0.0}, "default": lambda name, b: {},
            "doe": lambda name, b: {"accessory_power_W": doe_accessory_power_W(name, b["engine_displacement_L"])}}
    specs = [vehicle_from_mapping(gem_row(dict(basis, fuel=defaults["fuel"], engine_model_year=defaults["standard_year"],
                                               **load[accessories](name, basis)), name), Path(name))
             for name, basis in vehicles.items()]
    return {name: float(g) for name, g in zip(vehicles, idle_gallons_per_hour(specs)[1])}


def check_idle_fuel() -> list[dict]:
    """Each reference vehicle's no-load idle fuel against the measured truck of its class
    (idle_fuel_measured.toml): model (the engine alone) / measured; and, as brackets, the
    idle with the simulation's accessory load and with DOE's (Fact #861's trucks idled with
    their engine-driven accessories but no A/C and no fans)."""
    model, own, doe = (model_no_load_idle_gal_per_h(a) for a in ("none", "default", "doe"))
    rows = []
    for truck, m in measured_idle().items():
        rows += [dict(vehicle=name, measured_truck=truck, measured_gal_per_h=m["idle_gal_per_h"],
                      model_gal_per_h=round(model[name], 3), ratio=round(model[name] / m["idle_gal_per_h"], 3),
                      with_accessories_gal_per_h=round(own[name], 3),
                      with_doe_accessories_gal_per_h=round(doe[name], 3))
                 for name in m["reference"]]
    return rows


def measured_idle_additions() -> dict[str, float]:
    """{reference vehicle: measured - model no-load idle [gal/h]}: what the idle cycles would
    burn more if the engine idled as Fact #861's trucks (a sensitivity)."""
    return {r["vehicle"]: r["measured_gal_per_h"] - r["model_gal_per_h"] for r in check_idle_fuel()}


def doe_accessory_power_W(name: str | None, displacement_L: float) -> float:
    """DOE's accessory load [W] as NREL T3CO ships it (reference_inputs_doe_nrel.toml
    ``aux_kw``): the DOE vehicle ``name``'s own, else the one the file's
    ``accessory_by_service_class`` names for the engine's service class."""
    with open(HD_DIR / "reference_inputs_doe_nrel.toml", "rb") as fh:
        data = tomllib.load(fh)
    own = data["vehicles"].get(name)
    stand_in = data["vehicles"][data["accessory_by_service_class"][service_class(displacement_L)]]
    return 1000.0 * float((own or stand_in)["aux_kw"])


def doe_nrel_accessories() -> dict[str, dict]:
    """{reference vehicle: {accessory_power_W}}: DOE's accessory load for every reference
    vehicle (:func:`doe_accessory_power_W`; a sensitivity)."""
    _, vehicles = reference_vehicles()
    return {name: dict(accessory_power_W=doe_accessory_power_W(name, b["engine_displacement_L"]))
            for name, b in vehicles.items()}


def error_summary(errors) -> dict:
    e = np.asarray(errors, float)
    return dict(n=int(e.size), mean=round(float(e.mean()), 4), median=round(float(np.median(e)), 4),
                p05=round(float(np.percentile(e, 5)), 4), p95=round(float(np.percentile(e, 95)), 4),
                within_5pct=round(float(np.mean(np.abs(e) <= 0.05)), 4),
                median_abs=round(float(np.median(np.abs(e))), 4))


def error_groups(reference_rows: list[dict]) -> dict:
    """{test name: summary} of the mpg errors: tractors and vocational vehicles apart (they
    are validated to very different degrees, docs/validation-heavy-duty.md)."""
    groups = {"GEM_TRACTOR": [r for r in reference_rows if not r["gem_type"].startswith("vocational")],
              "GEM_VOCATIONAL": [r for r in reference_rows if r["gem_type"].startswith("vocational")]}
    return {name: error_summary([r["mpg_error"] for r in rows]) for name, rows in groups.items() if rows}


def write_error_file(reference_rows: list[dict]) -> None:
    lines = ['source = "validation/heavy_duty.py: EPA GEM Phase 2 reference vehicles (models/heavy_duty/'
             'gem_reference_vehicles.toml) on GEM cycles and weighting against their 40 CFR 1037 standards"',
             f'measured_on = "{datetime.date.today().isoformat()}"',
             'note = "relative error = predicted mpg / mpg at the standard - 1 (= standard CO2 / predicted CO2 - 1) '
             'of each reference vehicle\'s GEM composite; docs/validation-heavy-duty.md"', ""]
    for test, summary in error_groups(reference_rows).items():
        lines.append(f"[tests.{test}]")
        lines += [f"{k} = {v}" for k, v in summary.items()] + [""]
    ERROR_FILE.write_text("\n".join(lines) + "\n")


def plot(reference_rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [r["vehicle"] for r in reference_rows]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 4.5))
    ax.bar(x - 0.2, [r["standard_g_per_ton_mile"] for r in reference_rows], 0.4, label="standard (40 CFR 1037)")
    ax.bar(x + 0.2, [r["model_g_per_ton_mile"] for r in reference_rows], 0.4, label="fleetrun, GEM weighting")
    ax.set_xticks(x, names, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("g CO2 / ton-mile")
    ax.set_title("Phase 2 reference vehicles, model year %d" % reference_rows[0]["standard_year"])
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write models/heavy_duty/fuel_economy_error.toml")
    parser.add_argument("--plot", type=Path, help="bar chart of the reference vehicles (PNG)")
    args = parser.parse_args(argv)
    report = dict(typed_tractor=check_typed_tractor(), reference_vehicles=check_reference_vehicles(),
                  example_combination_trucks=check_example_combination_trucks(),
                  example_combination_trucks_gem=check_example_trucks_on_gem_weighting(),
                  example_mix_sensitivity=check_example_mix_sensitivity(),
                  fhwa_class_defaults=check_fhwa_class_defaults())
    report["idle_fuel_vs_measured"] = check_idle_fuel()
    report["reference_vehicles_measured_idle"] = check_reference_vehicles(idle_add_gal_per_h=measured_idle_additions())
    report["reference_vehicles_doe_nrel_accessories"] = check_reference_vehicles(columns=doe_nrel_accessories())
    report["example_combination_trucks_doe_accessories"] = check_example_combination_trucks(doe_accessories=True)
    report["reference_vehicles_stops_in_drive"] = check_reference_vehicles(stops_in_drive=True)
    report["reference_vehicles_stops_in_drive_measured_idle"] = check_reference_vehicles(
        stops_in_drive=True, idle_add_gal_per_h=measured_idle_additions())
    report["reference_error"] = error_groups(report["reference_vehicles"])
    report["reference_vehicles_doe_nrel_road_load"] = check_reference_vehicles(road_load=doe_nrel_road_load())
    report["reference_tractors_gem_bin_cda"] = check_reference_vehicles(road_load=gem_bin_road_load())
    report["engine_ramped_set"] = check_engine_ramped_set()
    report["tractor_gap"] = check_tractor_gap()
    print(json.dumps(report, indent=1))
    if args.write:
        write_error_file(report["reference_vehicles"])
    if args.plot:
        plot(report["reference_vehicles"], args.plot)
    return report


if __name__ == "__main__":
    main()
