"""Economy shifting of heavy diesels: gear choice around the engine's peak-torque speed.

fleetrun's shift schedule (fleetrun/simulation/transmission.py) picks the highest gear in
which the engine turns at least max(shift_speed_min_rpm, the speed that has the power with
reserve), and while the vehicle accelerates at least shift_speed_accel_rpm. The light-duty
defaults of that accelerating speed (models/transmissions.toml: 1,500-2,500 rpm, the
certification drivers' shift points of cars) would rev a heavy diesel rated at 1,800-2,100
rpm to its governor in every gear. Heavy trucks are driven the other way ("progressive
shifting", and the shift maps of automated manuals): upshift soon after the peak-torque speed,
cruise just below it. For medium- and heavy-duty diesel rows the three speeds are set
relative to the engine's peak-torque speed n_pk (factors in models/heavy_duty/drivelines.toml):

    shift_speed_min_rpm = k_min n_pk,  shift_speed_accel_rpm = k_accel n_pk,  launch_speed_rpm = k_launch n_pk.

A row's own column of the same name still wins (params._get reads it first).
"""
from __future__ import annotations

from fleetrun.resources import model_file
from fleetrun.simulation.records import EconomyShiftSpeeds

DRIVELINES_FILE = "heavy_duty/drivelines.toml"
HEAVY_DUTIES = ("MD", "HD")


def economy_shift_speeds_rpm(peak_torque_speed_rpm: float) -> EconomyShiftSpeeds:
    """Shift speeds [rpm] of a heavy diesel whose full-load torque peaks at
    ``peak_torque_speed_rpm``.

    Parameters
    ----------
    peak_torque_speed_rpm : float, [rpm]

    Returns
    -------
    EconomyShiftSpeeds [rpm] (fractions of the peak-torque speed from models/heavy_duty/drivelines.toml).

    >>> economy_shift_speeds_rpm(1200.0).shift_speed_min_rpm
    1020.0
    """
    k = model_file(DRIVELINES_FILE)["economy_shifting"]
    return EconomyShiftSpeeds(shift_speed_min_rpm=k["min_fraction"] * peak_torque_speed_rpm,
                              shift_speed_accel_rpm=k["accel_fraction"] * peak_torque_speed_rpm,
                              launch_speed_rpm=k["launch_fraction"] * peak_torque_speed_rpm)


def heavy_duty_shift_speeds(vehicle, peak_torque_speed_rpm: float) -> EconomyShiftSpeeds | None:
    """The economy shift speeds of a medium- or heavy-duty diesel ``vehicle`` (VehicleSpec);
    None for any other vehicle (it keeps its gearbox set's speeds).

    Parameters
    ----------
    vehicle : VehicleSpec
    peak_torque_speed_rpm : float, [rpm]

    Returns
    -------
    EconomyShiftSpeeds [rpm] or None.
    """
    if vehicle.fuel != "diesel" or vehicle.duty_class not in HEAVY_DUTIES:
        return None
    return economy_shift_speeds_rpm(peak_torque_speed_rpm)
