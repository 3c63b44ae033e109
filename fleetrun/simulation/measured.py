"""One measured number per vehicle: the optional Vehicles columns ``measured_ftp_mpg`` (the
vehicle's measured FTP composite, unadjusted) or its EPA label's figures (``label_combined_mpg``;
``label_city_mpg`` with ``label_highway_mpg``) calibrate its efficiency (docs/simulation.md "One
measured number").

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

A label's city and highway figures (``label_city_mpg`` and ``label_highway_mpg``, both given, no
measured FTP): the FTP at 25 C takes k_C, the city formula's scale (:func:`figure_scale`); the
HWFET at 25 C exp(w log k_H + (1 - w) h' log k), k_H the highway formula's scale and k the
combined figure's with h' (the combined figure, else the 55/45 combination of the two); every
other cycle, ambient and scenario k^s''. w, h' and s'' are models/technology.toml
``[label_split]`` ``blend_*`` (:func:`label_blend`; docs/validation-epa.md, F5).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fleetrun.physics import epa_label
from fleetrun.resources import model_file
from fleetrun.simulation.records import LabelBlend, LabelSplit

NOMINAL_AMBIENT_C = 25.0        # EPA test cell (40 CFR 86.130: 20-30 C)
FIGURES = ("measured_ftp_mpg", "label_combined_mpg", "label_city_mpg", "label_highway_mpg")


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


def label_blend() -> LabelBlend:
    """The route of a label's city and highway figures (models/technology.toml ``[label_split]``
    ``blend_*``).

    Returns
    -------
    LabelBlend: ``highway_share`` h', ``weight`` w, ``transfer_share`` s'' [-].
    """
    m = model_file("technology.toml")["label_split"]
    return LabelBlend(float(m["blend_highway_share"]), float(m["blend_weight"]), float(m["blend_other_cycles_share"]))


def measured_figures(vehicles) -> dict[str, np.ndarray]:
    """Each optional figure (``FIGURES``) per vehicle [mpg], NaN where blank.

    Parameters
    ----------
    vehicles : sequence of vehicle records, with the optional attributes of ``FIGURES`` [mpg]

    Returns
    -------
    dict figure name -> float array of shape (V,).
    """
    def column(name):
        return np.array([np.nan if getattr(v, name, None) is None else float(getattr(v, name)) for v in vehicles])
    return {name: column(name) for name in FIGURES}


def calibrated(figures) -> np.ndarray:
    """Which vehicles a figure calibrates: a measured FTP, a label's combined figure, or its city
    and highway figures together (one of the pair alone is ignored, with a warning from the
    workbook's row check).

    Parameters
    ----------
    figures : dict from :func:`measured_figures`

    Returns
    -------
    bool array of shape (V,).
    """
    def given(name):
        return np.isfinite(figures[name])
    return (given("measured_ftp_mpg") | given("label_combined_mpg")
            | (given("label_city_mpg") & given("label_highway_mpg")))


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
    city, highway = (_formula(kind, model_years, label_set) for kind in epa_label.KINDS)
    share = epa_label.CITY_SHARE
    a = share * city[0] + (1 - share) * highway[0]
    b_ftp = share * city[1] / np.asarray(ftp_mpg, float)
    b_hwfet = (1 - share) * highway[1] / np.asarray(hwfet_mpg, float)
    target = 1.0 / np.asarray(label_combined_mpg, float)
    a, b_ftp, b_hwfet, target = _shared_by_group((a, b_ftp, b_hwfet, target), groups)
    return split_root(target - a, b_ftp, b_hwfet, highway_share)


def _formula(kind, model_years, label_set):
    """(intercept [gal/mi], slope [-]) of the ``kind`` ("city" or "highway") label formula: the
    set ``label_set``, else each model year's (fleetrun.physics.epa_label), else the set of a row
    without a model year."""
    if label_set is None and model_years is None:
        label_set = epa_label.set_for_model_year(None)
    return getattr(label_set, kind) if label_set is not None else epa_label.coefficients(model_years, kind)


def _shared_by_group(arrays, groups):
    """``arrays`` broadcast together, each entry replaced by its label group's mean over the
    vehicles where every array is finite (:func:`group_mean`); as given when ``groups`` is None."""
    if groups is None:
        return arrays
    arrays = np.broadcast_arrays(*arrays)
    valid = np.logical_and.reduce([np.isfinite(x) for x in arrays])
    return tuple(group_mean(x, groups, valid) for x in arrays)


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


def figure_scale(figure_mpg, sim_mpg, kind, model_years=None, label_set=None, groups=None):
    """k that makes one label formula (``kind``: "city" of the FTP, "highway" of the HWFET) of
    the simulated mpg / k give the label's figure; vehicles of one group share k (the mean of
    their label fuel per mile is the mean of their figures').

    Parameters
    ----------
    figure_mpg : array, the label's city or highway figure [mpg] (NaN: not given)
    sim_mpg : array, simulated FTP (city) or HWFET (highway) fuel economy [mpg]
    kind : str, "city" or "highway"
    model_years, label_set, groups : as :func:`label_scale`

    Returns
    -------
    fuel scale [-] per vehicle.
    """
    a, b = _formula(kind, model_years, label_set)
    target = 1.0 / np.asarray(figure_mpg, float)
    slope = b / np.asarray(sim_mpg, float)
    a, target, slope = _shared_by_group((a, target, slope), groups)
    return (target - a) / slope


def cycle_factors(figures, sim_ftp_mpg, sim_hwfet_mpg, model_years=None, groups=None) -> np.ndarray:
    """Fuel multipliers per vehicle on (the FTP at 25 C, the HWFET at 25 C, any other cycle,
    ambient or scenario): a measured FTP: k, k^s, k^s; a label: k, k^h, k^s' (:func:`label_split`);
    a label with city and highway figures: k_C, the blend, k^s'' (:func:`label_blend`); 1 where
    no figure is given. A row without a combined figure takes the 55/45 mean of its city and
    highway figures.

    Parameters
    ----------
    figures : dict from :func:`measured_figures`
    sim_ftp_mpg, sim_hwfet_mpg : array, simulated FTP and HWFET at 25 C, uncalibrated [mpg]
    model_years, groups : as :func:`label_scale` (a vehicle with a measured FTP takes no part in
        its group)

    Returns
    -------
    array (V, 3) of fuel multipliers [-].
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        k_ftp = np.asarray(sim_ftp_mpg, float) / figures["measured_ftp_mpg"]
        measured = np.isfinite(k_ftp)
        city, highway = (np.where(measured, np.nan, figures[f]) for f in ("label_city_mpg", "label_highway_mpg"))
        both = np.isfinite(city) & np.isfinite(highway)
        pair = 1.0 / (epa_label.CITY_SHARE / city + (1.0 - epa_label.CITY_SHARE) / highway)
        combined = np.where(measured, np.nan, np.where(np.isfinite(figures["label_combined_mpg"]),
                                                       figures["label_combined_mpg"], pair))
        split, blend, s = label_split(), label_blend(), transfer_share()
        k = label_scale(combined, sim_ftp_mpg, sim_hwfet_mpg, model_years, groups=groups,
                        highway_share=split.highway_share)
        out = np.c_[k, k ** split.highway_share, k ** split.transfer_share]
        if both.any():
            out[both] = _blend_factors(np.where(both, combined, np.nan), np.where(both, city, np.nan),
                                       np.where(both, highway, np.nan), sim_ftp_mpg, sim_hwfet_mpg,
                                       model_years, groups, blend)[both]
        out[measured] = np.c_[k_ftp, k_ftp ** s, k_ftp ** s][measured]
    return np.where(np.isfinite(out), out, 1.0)


def _blend_factors(combined, city, highway, sim_ftp, sim_hwfet, model_years, groups, blend):
    """(V, 3) multipliers of the city-and-highway route (:func:`cycle_factors`)."""
    k = label_scale(combined, sim_ftp, sim_hwfet, model_years, groups=groups, highway_share=blend.highway_share)
    k_city = figure_scale(city, sim_ftp, "city", model_years, groups=groups)
    k_highway = figure_scale(highway, sim_hwfet, "highway", model_years, groups=groups)
    hw = np.exp(blend.weight * np.log(k_highway) + (1.0 - blend.weight) * blend.highway_share * np.log(k))
    return np.c_[k_city, hw, k ** blend.transfer_share]


def factor_on(factors, cycle_name, at_nominal) -> np.ndarray:
    """The column of :func:`cycle_factors` for ``cycle_name`` at the ambient (``at_nominal``: EPA's 25 C).

    Parameters
    ----------
    factors : array (V, 3), :func:`cycle_factors`
    cycle_name : str, the simulated cycle
    at_nominal : bool, the ambient is EPA's nominal 25 C

    Returns
    -------
    array (V,), fuel multiplier [-].
    """
    column = 0 if at_nominal and cycle_name == "FTP" else 1 if at_nominal and cycle_name == "HWFET" else 2
    return factors[:, column]


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
