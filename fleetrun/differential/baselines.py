"""Physics baselines for the differential, registered by name in ``fleetrun.registry.PHYSICS``.

- ``thesis``: Appendix B as printed, quirks included (docs/thesis-quirks.md); lubricant at
  the fixed 70 C of B.7 unless an oil temperature is given.
- ``vecto-generic``: VECTO's generic axle loss map, for comparison with the EU tool.
"""
from __future__ import annotations

import numpy as np

from fleetrun.differential.configurations import reference_capacity_Nm, thesis_efficiency
from fleetrun.errors import DomainError
from fleetrun.physics.lubricant import THESIS_OPERATING_TEMP_C
from fleetrun.registry import PHYSICS


class ThesisBaseline:
    name = "thesis"
    description = "Vaughn (2012) Appendix B code as printed, quirks included"

    def efficiency(self, configuration, torque_fraction, speed_rpm, gear_ratio, *, low_gear_ratio=None,
                   axle_gear="high", oil_temp_C=None, kim_torque_scale_Nm=None):
        # Kim scaling maps the fraction onto the reference differential: the vehicle's own
        # scale plays no further part (thesis Sec. 5.2.1.A).
        temp = THESIS_OPERATING_TEMP_C if oil_temp_C is None else float(oil_temp_C)
        return thesis_efficiency(configuration, torque_fraction, speed_rpm, gear_ratio,
                                 low_gear_ratio=low_gear_ratio, axle_gear=axle_gear, oil_temp_C=temp)


def vecto_generic_drag_torque_Nm(axle_ratio):
    """VECTO generic axle: wheel-side drag torque at zero load, ``Td0 = 52.5 + 15 i`` [N m].

    Parameters
    ----------
    axle_ratio : float or array, axle ratio i [-]

    Returns
    -------
    wheel-side drag torque Td0 [N m], the shape of ``axle_ratio``.
    """
    return 52.5 + 15 * np.asarray(axle_ratio, dtype=float)


def vecto_generic_output_torque_Nm(input_torque_Nm, output_speed_rpm, axle_ratio):
    """Output torque of VECTO's generic axle loss map, solved for a given input torque.

    The map gives the loss on the wheel side, ``T_loss = 0.5 Td0 + 0.5 Td0 n_out / 150 rpm
    + |T_out| (1/0.98 - 1)``, and ``T_in i = T_out + T_loss``. For T_out >= 0 this solves to
    ``T_out = 0.98 (T_in i - 0.5 Td0 (1 + n_out/150))``; below zero the axle does not drive
    (returned as is, negative, so the caller can floor it).

    Parameters
    ----------
    input_torque_Nm : float or array, axle input torque T_in [N m]
    output_speed_rpm : float or array, axle output speed n_out [rpm]
    axle_ratio : float or array, axle ratio i [-]

    Returns
    -------
    output torque T_out [N m], negative where the drag exceeds the input.
    """
    td0 = vecto_generic_drag_torque_Nm(axle_ratio)
    drag = 0.5 * td0 + 0.5 * td0 * np.asarray(output_speed_rpm, dtype=float) / 150.0
    return 0.98 * (np.asarray(input_torque_Nm, dtype=float) * axle_ratio - drag)


class VectoGenericBaseline:
    name = "vecto-generic"
    description = "VECTO generic axle loss map: Td0 = 52.5 + 15 i N m, 98 % load-dependent"

    def efficiency(self, configuration, torque_fraction, speed_rpm, gear_ratio, *, low_gear_ratio=None,
                   axle_gear="high", oil_temp_C=None, kim_torque_scale_Nm=None):
        if not configuration.startswith("HD"):
            raise DomainError(f"physics 'vecto-generic' covers heavy-duty axles only, not {configuration}",
                              hint="VECTO is the EU heavy-duty tool; use --physics thesis for light-duty")
        # Absolute torque from the fraction: the vehicle's Kim scale when known, else the
        # capacity of the configuration's driving axle (what the thesis maps fractions onto).
        capacity = (reference_capacity_Nm(configuration) if kim_torque_scale_Nm is None
                    else float(kim_torque_scale_Nm))
        ratio = gear_ratio * (low_gear_ratio if (low_gear_ratio and axle_gear == "low") else 1.0)
        tin = np.asarray(torque_fraction, dtype=float) * capacity
        n_out = np.asarray(speed_rpm, dtype=float) / ratio
        tout = vecto_generic_output_torque_Nm(tin, n_out, ratio)
        with np.errstate(all="ignore"):
            eta = np.where(tin > 0, tout / (tin * ratio), 0.0)
        return np.clip(eta, 0.0, 1.0)


PHYSICS.register("thesis", ThesisBaseline())
PHYSICS.register("vecto-generic", VectoGenericBaseline())
