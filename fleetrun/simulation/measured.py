"""One measured number per vehicle: the optional Vehicles columns ``measured_ftp_mpg`` (the
vehicle's measured FTP composite, unadjusted) or ``label_combined_mpg`` (its EPA label
combined figure) calibrate its efficiency (docs/simulation.md "One measured number").

The vehicle's fuel scale k = simulated / measured mpg on the figure's own test (FTP at EPA's
nominal 25 C; for a label: FTP and HWFET through EPA's derived 5-cycle label formulas, 40 CFR
600.210-12, combined 55 % city, 45 % highway, with the coefficient set of the vehicle's model
year, fleetrun.physics.epa_label). On that test the fuel is multiplied by k exactly; on every
other cycle, ambient and scenario by k^s, with s = ``transfer_share`` of models/technology.toml:
one global constant fitted with manufacturers held out (validation/epa_technology.py).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fleetrun.physics import epa_label
from fleetrun.resources import model_file

NOMINAL_AMBIENT_C = 25.0        # EPA test cell (40 CFR 86.130: 20-30 C)
FIGURES = ("measured_ftp_mpg", "label_combined_mpg")


def transfer_share() -> float:
    """The share (in log) of a vehicle's calibration carried to other cycles (models/technology.toml).

    Returns
    -------
    float, the transfer share s [-] (``fitted.transfer_share``).
    """
    return float(model_file("technology.toml")["fitted"]["transfer_share"])


def measured_figures(vehicles) -> tuple[np.ndarray, np.ndarray]:
    """(measured FTP, label combined) mpg per vehicle, NaN where blank.

    Parameters
    ----------
    vehicles : sequence of vehicle records, with the optional attributes ``measured_ftp_mpg`` and
        ``label_combined_mpg`` [mpg]

    Returns
    -------
    (measured FTP [mpg], label combined [mpg]), float arrays of shape (V,).
    """
    def column(name):
        return np.array([np.nan if getattr(v, name, None) is None else float(getattr(v, name)) for v in vehicles])
    return column("measured_ftp_mpg"), column("label_combined_mpg")


def label_scale(label_combined_mpg, ftp_mpg, hwfet_mpg, model_years=None, label_set=None, groups=None):
    """Fuel scale k that makes the label formulas of the simulated FTP and HWFET mpg (both divided
    by k) give ``label_combined_mpg``: 1/label = a + k b, linear in k. Vehicles of one label group
    share one k: the mean of their label fuel per mile is the mean of their labels' (a label is its
    model type's configurations' mean, 40 CFR 600.208-12; equal weights; docs/simulation.md).

    Parameters
    ----------
    label_combined_mpg : float or array, the EPA label combined figure [mpg]
    ftp_mpg : float or array, simulated FTP fuel economy [mpg]
    hwfet_mpg : float or array, simulated HWFET fuel economy [mpg]
    model_years : sequence of int or None, or None: each vehicle's model year, which chooses the
        label formulas' coefficients (fleetrun.physics.epa_label; None: no vehicle has one)
    label_set : LabelSet or None, one coefficient set for every vehicle instead (validation)
    groups : sequence of str or None, or None: each vehicle's label group (None or "": alone)

    Returns
    -------
    fuel scale k [-], the broadcast shape of the arguments.
    """
    if label_set is None and model_years is None:
        label_set = epa_label.set_for_model_year(None)
    if label_set is not None:
        city, highway = label_set.city, label_set.highway
    else:
        city, highway = (epa_label.coefficients(model_years, kind) for kind in epa_label.KINDS)
    share = epa_label.CITY_SHARE
    a = share * city[0] + (1 - share) * highway[0]
    b = share * city[1] / ftp_mpg + (1 - share) * highway[1] / hwfet_mpg
    target = 1.0 / np.asarray(label_combined_mpg, float)
    if groups is not None:
        a, b, target = np.broadcast_arrays(a, b, target)
        valid = np.isfinite(a) & np.isfinite(b) & np.isfinite(target)
        a, b, target = (group_mean(x, groups, valid) for x in (a, b, target))
    return (target - a) / b


def group_mean(values, groups, valid):
    """Each valid entry replaced by the mean over the valid entries of its group.

    Parameters
    ----------
    values : array, one value per vehicle
    groups : sequence of str or None, each vehicle's group (None, NaN or "": a group of its own)
    valid : array of bool, the entries that count (the others are returned as they are)

    Returns
    -------
    float array, the shape of ``values``.
    """
    values = np.array(values, dtype=float)
    keys = np.array(["" if epa_label.is_missing(g) else str(g) for g in groups], dtype=object)
    use = np.asarray(valid, bool) & (keys != "")
    if use.any():
        _, inverse = np.unique(keys[use], return_inverse=True)
        values[use] = (np.bincount(inverse, weights=values[use]) / np.bincount(inverse))[inverse]
    return values


def fuel_scale(measured_ftp_mpg, label_combined_mpg, sim_ftp_mpg, sim_hwfet_mpg, model_years=None, groups=None):
    """k per vehicle (fuel multiplier on the calibration test): simulated / measured FTP mpg, else
    from the label; NaN where neither figure is given.

    Parameters
    ----------
    measured_ftp_mpg : float or array, measured FTP composite [mpg] (NaN: not given)
    label_combined_mpg : float or array, EPA label combined figure [mpg] (NaN: not given)
    sim_ftp_mpg : float or array, simulated FTP fuel economy [mpg]
    sim_hwfet_mpg : float or array, simulated HWFET fuel economy [mpg]
    model_years : sequence of int or None, or None: each vehicle's model year (its label formulas,
        :func:`label_scale`)
    groups : sequence of str or None, or None: each vehicle's label group (:func:`label_scale`;
        a vehicle with a measured FTP takes no part in its group)

    Returns
    -------
    fuel scale k [-] per vehicle, NaN where neither figure is given.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        from_ftp = np.asarray(sim_ftp_mpg, float) / np.asarray(measured_ftp_mpg, float)
        label = np.where(np.isfinite(from_ftp), np.nan, np.asarray(label_combined_mpg, float))
        return np.where(np.isfinite(from_ftp), from_ftp, label_scale(label, sim_ftp_mpg, sim_hwfet_mpg,
                                                                     model_years, groups=groups))


def carried_scale(k, exact, share):
    """The fuel multiplier on a cycle: k on the calibration test itself (``exact``), k^share elsewhere.

    Parameters
    ----------
    k : float or array, fuel scale on the calibration test [-] (NaN: uncalibrated)
    exact : bool or array, the cycle is the calibration test itself
    share : float, the transfer share s [-] (:func:`transfer_share`)

    Returns
    -------
    fuel multiplier [-], 1 where ``k`` is NaN.
    """
    k = np.asarray(k, float)
    return np.where(np.isfinite(k), np.where(exact, k, k ** share), 1.0)


def scale_result(result, factor):
    """A FleetCycleResult with its fuel (totals, phases, trace fuel rate) multiplied by ``factor`` (V,).

    Parameters
    ----------
    result : FleetCycleResult, one cycle's simulation result (fleetrun.simulation.records)
    factor : array, fuel multiplier per vehicle [-], (V,)

    Returns
    -------
    FleetCycleResult, a copy with fuel [g], [gal] and fuel rate [g/s] times ``factor`` and mpg divided by it.
    """
    phases = {name: replace(p, fuel_g=p.fuel_g * factor, fuel_gal=p.fuel_gal * factor, mpg=p.mpg / factor)
              for name, p in result.phases.items()}
    trace = (None if result.trace is None else
             replace(result.trace, fuel_rate_g_per_s=result.trace.fuel_rate_g_per_s * factor[:, None]))
    return replace(result, fuel_g=result.fuel_g * factor, fuel_gal=result.fuel_gal * factor, mpg=result.mpg / factor,
                   phases=phases, trace=trace)
