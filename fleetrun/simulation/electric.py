"""Battery-electric vehicles: energy from the wall over a drive cycle, from the same road load.

The wheels' demand is the road-load force of :mod:`fleetrun.simulation.road_load` (EPA
coastdown coefficients, effective mass, grade) over the cycle's speed trace, step by step as in
the backward simulation. The chain from the wheels back to the wall (constants in
``models/electric.toml``, docs/report.md "Electric vehicles"):

- driving (wheel power P > 0): battery power = P / drive efficiency;
- braking (P < 0): battery power = P x regenerative share x regenerative efficiency (the
  motor recovers part of the braking energy, friction brakes the rest);
- accessories: a constant power while the car is on;
- charging: wall energy = battery energy / charging efficiency (the EPA label counts energy
  from the wall, SAE J1634).

The result is the dynamometer (cycle) energy; the on-road factor (EPA's 0.7 for labels) is the
budget's (:func:`fleetrun.budget.arithmetic.electric_onroad_factor`).
"""
from __future__ import annotations


import numpy as np

from fleetrun.resources import model_file
from fleetrun.simulation.records import ElectricConstants
from fleetrun.simulation.road_load import ROTATING_MASS_FRACTION, coastdown_to_si, tractive_force_N
from fleetrun.units import METERS_PER_MILE

J_PER_KWH = 3.6e6


def constants() -> ElectricConstants:
    """``models/electric.toml`` as :class:`ElectricConstants`.

    Returns
    -------
    ElectricConstants (efficiencies [-], accessory power [W]).
    """
    return ElectricConstants(**model_file("electric.toml"))


def battery_power_W(wheel_power_W, drive_efficiency, regen_share, regen_efficiency):
    """Battery power [W] for a wheel power [W]: P / eta_drive when driving, P x share x
    eta_regen when braking (negative: the battery is charged).

    Parameters
    ----------
    wheel_power_W : array_like
        Power the driven wheels put on the road [W]; negative while braking.
    drive_efficiency : float
        Battery -> wheels [-].
    regen_share : float
        Share of the braking energy the motor takes [-].
    regen_efficiency : float
        Wheels -> battery [-].

    Returns
    -------
    battery power [W], the shape of ``wheel_power_W``.

    >>> battery_power_W([9000.0, -10000.0], 0.9, 0.8, 0.9).tolist()
    [10000.0, -7200.0]
    """
    p = np.asarray(wheel_power_W, dtype=float)
    return np.where(p > 0.0, p / drive_efficiency, p * regen_share * regen_efficiency)


def wall_energy_J(battery_energy_J, charging_efficiency):
    """Energy drawn from the wall [J] to put ``battery_energy_J`` back: E / eta_charge.

    Parameters
    ----------
    battery_energy_J : float or array, energy to put back into the battery [J]
    charging_efficiency : float, wall -> battery [-]

    Returns
    -------
    energy from the wall [J].

    >>> float(wall_energy_J(9.0e6, 0.9))
    10000000.0
    """
    return np.asarray(battery_energy_J, dtype=float) / charging_efficiency


def step_kinematics(time_s, speed_mps, grade_pct):
    """Per step between samples: duration [s], mean speed [m/s], acceleration [m/s^2] and
    mean grade [%] (the backward simulation's step convention).

    Parameters
    ----------
    time_s : array (N,), sample times [s]
    speed_mps : array (N,), speed [m/s]
    grade_pct : array (N,), grade [%]

    Returns
    -------
    (dt [s], mean speed [m/s], acceleration [m/s^2], mean grade [%]), arrays (N - 1,).
    """
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(speed_mps, dtype=float)
    g = np.asarray(grade_pct, dtype=float)
    dt = np.diff(t)
    return dt, 0.5 * (v[1:] + v[:-1]), np.diff(v) / dt, 0.5 * (g[1:] + g[:-1])


def simulate_electric(vehicles, cycle) -> dict[str, np.ndarray]:
    """Per vehicle over ``cycle`` (a DriveCycle): ``miles``, ``kwh`` (from the wall, dynamometer),
    ``wheel_energy_J`` (positive traction), ``drivetrain_input_energy_J`` (battery energy for
    traction) and ``battery_energy_J`` (net, accessories included).

    Parameters
    ----------
    vehicles : list of VehicleSpec, battery-electric rows (coastdown, test weight, duty class)
    cycle : DriveCycle, the speed and grade trace

    Returns
    -------
    dict, column name -> array (V,): ``miles`` [mi], ``kwh`` [kWh from the wall],
    ``wheel_energy_J``, ``drivetrain_input_energy_J``, ``battery_energy_J`` [J].
    """
    c = constants()
    dt, v, a, grade = step_kinematics(cycle.time_s, cycle.speed_mps, cycle.grade_pct)
    A, B, C = coastdown_to_si([x.coastdown_A_lbf for x in vehicles], [x.coastdown_B_lbf_per_mph for x in vehicles],
                              [x.coastdown_C_lbf_per_mph2 for x in vehicles])
    mass = np.array([x.test_weight_kg for x in vehicles], dtype=float)[:, None]
    rot = np.array([ROTATING_MASS_FRACTION[x.duty_class] for x in vehicles])[:, None]
    force = tractive_force_N(v[None, :], a[None, :], grade[None, :], mass, rot, A[:, None], B[:, None], C[:, None])
    wheel_W = force * v[None, :]
    battery_W = battery_power_W(wheel_W, c.drive_efficiency, c.regen_share, c.regen_efficiency)
    traction_J = (np.where(wheel_W > 0, wheel_W, 0.0) * dt).sum(axis=1)
    battery_J = (battery_W * dt).sum(axis=1) + c.accessory_power_W * float(dt.sum())
    miles = np.full(len(vehicles), float((v * dt).sum()) / METERS_PER_MILE)
    return {"miles": miles, "kwh": wall_energy_J(battery_J, c.charging_efficiency) / J_PER_KWH,
            "wheel_energy_J": traction_J, "drivetrain_input_energy_J": traction_J / c.drive_efficiency,
            "battery_energy_J": battery_J}
