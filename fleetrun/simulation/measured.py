"""One measured number per vehicle: the optional Vehicles columns ``measured_ftp_mpg`` (the
vehicle's measured FTP composite, unadjusted) or ``label_combined_mpg`` (its EPA label
combined figure) calibrate its efficiency (docs/simulation.md "One measured number").

The vehicle's fuel scale k = simulated / measured mpg on the figure's own test (FTP at EPA's
nominal 25 C). On that test the fuel is multiplied by k exactly; on every other cycle, ambient
and scenario by k^s, with s = ``transfer_share`` of models/technology.toml: one global constant
fitted with manufacturers held out (validation/epa_technology.py).

A label: EPA's derived 5-cycle label formulas (40 CFR 600.210-12, combined 55 % city, 45 %
highway, the coefficient set of the vehicle's model year, fleetrun.physics.epa_label) of the
simulated FTP / k and HWFET / k^h give the label; the FTP at 25 C takes k, the HWFET at 25 C
k^h, every other cycle, ambient and scenario k^s'. h and s' are models/technology.toml
``[label_split]``, fitted on real MY2022 labels with manufacturers held out
(validation/epa_label_sources.py, docs/validation-epa.md "Where the label route's misses come
from").
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fleetrun.physics import epa_label
from fleetrun.resources import model_file
from fleetrun.simulation.records import LabelSplit

NOMINAL_AMBIENT_C = 25.0        # EPA test cell (40 CFR 86.130: 20-30 C)
FIGURES = ("measured_ftp_mpg", "label_combined_mpg")


def transfer_share() -> float:
    """The share (in log) of a vehicle's calibration carried to other cycles (models/technology.toml).

    Returns
    -------
    float, the transfer share s [-] (``fitted.transfer_share``).
    """
    return float(model_file("technology.toml")["fitted"]["transfer_share"])


def label_split() -> LabelSplit:
    """The label route's global split (models/technology.toml ``[label_split]``).

    Returns
    -------
    LabelSplit: ``highway_share`` h [-] (the HWFET at 25 C takes k^h) and ``transfer_share`` s'
    [-] (every other cycle, ambient and scenario takes k^s'; the file's ``other_cycles_share``).
    """
    m = model_file("technology.toml")["label_split"]
    return LabelSplit(float(m["highway_share"]), float(m["other_cycles_share"]))


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


def label_scale(label_combined_mpg, ftp_mpg, hwfet_mpg, model_years=None, label_set=None, groups=None,
                highway_share=1.0):
    """Fuel scale k that makes the label formulas of the simulated FTP mpg / k and HWFET mpg /
    k^h give ``label_combined_mpg``: 1/label = a + k b_FTP + k^h b_HWFET (h = 1: linear in k).
    Vehicles of one label group share one k: the mean of their label fuel per mile is the mean of
    their labels' (a label is its model type's configurations' mean, 40 CFR 600.208-12; equal
    weights; docs/simulation.md).

    Parameters
    ----------
    label_combined_mpg : float or array, the EPA label combined figure [mpg]
    ftp_mpg : float or array, simulated FTP fuel economy [mpg]
    hwfet_mpg : float or array, simulated HWFET fuel economy [mpg]
    model_years : sequence of int or None, or None: each vehicle's model year, which chooses the
        label formulas' coefficients (fleetrun.physics.epa_label; None: no vehicle has one)
    label_set : LabelSet or None, one coefficient set for every vehicle instead (validation)
    groups : sequence of str or None, or None: each vehicle's label group (None or "": alone)
    highway_share : float, h [-]: the HWFET takes k^h (1: the same k as the FTP;
        :func:`label_split` gives the stored value)

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
    b_ftp = share * city[1] / np.asarray(ftp_mpg, float)
    b_hwfet = (1 - share) * highway[1] / np.asarray(hwfet_mpg, float)
    target = 1.0 / np.asarray(label_combined_mpg, float)
    if groups is not None:
        a, b_ftp, b_hwfet, target = np.broadcast_arrays(a, b_ftp, b_hwfet, target)
        valid = np.isfinite(a) & np.isfinite(b_ftp) & np.isfinite(b_hwfet) & np.isfinite(target)
        a, b_ftp, b_hwfet, target = (group_mean(x, groups, valid) for x in (a, b_ftp, b_hwfet, target))
    return split_root(target - a, b_ftp, b_hwfet, highway_share)


def split_root(rhs, b_ftp, b_hwfet, highway_share, iterations=40):
    """Root k > 0 of b_ftp k + b_hwfet k^h = rhs (Newton in log k from the h = 1 root; the left
    side is increasing and convex in log k, so the iteration converges monotonically).

    Parameters
    ----------
    rhs : array, label fuel per mile minus the formulas' intercepts [gal/mi]
    b_ftp, b_hwfet : array, the FTP and HWFET terms' slopes per unit k [gal/mi]
    highway_share : float, h [-]
    iterations : int, Newton steps

    Returns
    -------
    k [-], NaN where ``rhs`` <= 0 (no positive scale gives the label).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        k = rhs / (b_ftp + b_hwfet)
        if highway_share == 1.0:
            return k
        x = np.log(np.where(k > 0, k, np.nan))
        for _ in range(iterations):
            f_ftp, f_hwfet = b_ftp * np.exp(x), b_hwfet * np.exp(highway_share * x)
            x = x - (f_ftp + f_hwfet - rhs) / (f_ftp + highway_share * f_hwfet)
        return np.exp(x)


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
        return np.where(np.isfinite(from_ftp), from_ftp, label_scale(
            label, sim_ftp_mpg, sim_hwfet_mpg, model_years, groups=groups,
            highway_share=label_split().highway_share))


def carried_scale(k, from_label, cycle_name, at_nominal):
    """The fuel multiplier on a cycle. A measured FTP: k on the FTP at 25 C, k^s elsewhere
    (:func:`transfer_share`). A label: k on the FTP at 25 C, k^h on the HWFET at 25 C, k^s'
    elsewhere (:func:`label_split`).

    Parameters
    ----------
    k : float or array, fuel scale on the calibration (:func:`fuel_scale`) [-] (NaN: uncalibrated)
    from_label : bool or array, k comes from a label figure (not a measured FTP)
    cycle_name : str, the simulated cycle
    at_nominal : bool, the ambient is EPA's nominal 25 C

    Returns
    -------
    fuel multiplier [-], 1 where ``k`` is NaN.
    """
    k = np.asarray(k, float)
    split = label_split()
    if at_nominal and cycle_name == "FTP":
        power = np.ones_like(k)
    elif at_nominal and cycle_name == "HWFET":
        power = np.where(from_label, split.highway_share, transfer_share())
    else:
        power = np.where(from_label, split.transfer_share, transfer_share())
    return np.where(np.isfinite(k), k ** power, 1.0)


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
