"""The coastdown's driveline part (fleetrun/simulation/coastdown_driveline.py): what is removed
is the drivetrain model's own no-load loss, computed independently here."""
import numpy as np
import pytest

from fleetrun.errors import InputError
from fleetrun.simulation import coastdown_driveline as cd
from fleetrun.simulation import diffmodes
from fleetrun.simulation.core import DifferentialSolver
from fleetrun.simulation.params import vehicle_arrays
from fleetrun.testing.vehicles import CAMRY
from fleetrun.units import RAD_S_PER_RPM


def _camry(mode="direct"):
    va = vehicle_arrays([CAMRY])
    return va, DifferentialSolver(va, mode, "thesis", 25.0, None)


def test_default_is_off_and_none_leaves_the_road_load():
    # off until the held-out validation improves on every cycle (docs/validation-epa.md)
    assert cd.default_variant() == "none"
    va, solver = _camry()
    assert cd.remove_driveline_spin(va, solver, "none") is va


def test_differential_removes_the_thesis_chain_no_load_loss():
    # the removed a + b v is the least-squares line through the differential's own loss at zero
    # output torque (diffmodes.invert_direct, the thesis chain), at the wheels, over 15-115 km/h
    va, solver = _camry()
    v = cd.COASTDOWN_SPEEDS_MPS
    rpm = v / va.radius_m[0] / RAD_S_PER_RPM * va.final_drive[0]
    frac = diffmodes.invert_direct(va.configuration[0], np.zeros(v.size), rpm, va.final_drive[0], None, False,
                                   "thesis", 25.0, diffmodes.map_torque_scale_Nm("thesis", va.kim_torque_scale_Nm[0]))
    force = frac * va.kim_torque_scale_Nm[0] * va.final_drive[0] / va.radius_m[0]
    b, a = np.polyfit(v, force, 1)
    out = cd.remove_driveline_spin(va, solver, "differential")
    assert va.A_N[0] - out.A_N[0] == pytest.approx(a, rel=1e-6)
    assert va.B_N[0] - out.B_N[0] == pytest.approx(b, rel=1e-6)
    # a small part of the road load: 1-5 % of the coastdown force at 50 mph for this car
    share = (a + b * 22.35) / (va.A_N[0] + va.B_N[0] * 22.35 + va.C_N[0] * 22.35**2)
    assert 0.001 < share < 0.05


def test_gearbox_variant_removes_more_and_unknown_names_list_the_valid_ones():
    va, solver = _camry()
    diff = cd.remove_driveline_spin(va, solver, "differential")
    both = cd.remove_driveline_spin(va, solver, "differential_gearbox")
    assert both.A_N[0] < diff.A_N[0] and both.B_N[0] <= diff.B_N[0]
    with pytest.raises(InputError, match="differential_gearbox"):
        cd.remove_driveline_spin(va, solver, "diferential")
