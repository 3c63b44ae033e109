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

DRIVELINES_FILE = "heavy_duty/drivelines.toml"
HEAVY_DUTIES = ("MD", "HD")


def economy_shift_speeds_rpm(peak_torque_speed_rpm: float) -> dict:
    """shift_speed_min_rpm, shift_speed_accel_rpm and launch_speed_rpm [rpm] of a heavy diesel
    whose full-load torque peaks at ``peak_torque_speed_rpm``."""
    k = model_file(DRIVELINES_FILE)["economy_shifting"]
    return {"shift_speed_min_rpm": k["min_fraction"] * peak_torque_speed_rpm,
            "shift_speed_accel_rpm": k["accel_fraction"] * peak_torque_speed_rpm,
            "launch_speed_rpm": k["launch_fraction"] * peak_torque_speed_rpm}


def with_heavy_duty_shifting(transmission_set: dict, vehicle, peak_torque_speed_rpm: float) -> dict:
    """``transmission_set`` (params.transmission_defaults) with the economy shift speeds for a
    medium- or heavy-duty diesel ``vehicle``; other vehicles' sets are returned unchanged."""
    if vehicle.fuel != "diesel" or vehicle.duty_class not in HEAVY_DUTIES:
        return transmission_set
    return {**transmission_set, **economy_shift_speeds_rpm(peak_torque_speed_rpm)}
