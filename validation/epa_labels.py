"""Real MY2022 window-sticker labels (fueleconomy.gov ``vehicles.csv``, the rows shipped in
inputs/fueleconomy/vehicles_my2022.csv) joined to the vehicles of the EPA 2022 Test Car List as
`fleetrun import-epa` builds them (docs/validation-epa.md "Real labels"):

    PYTHONPATH=. python validation/epa_labels.py [--list FILE]

The join rule (one Test Car List vehicle = one ``vehicle_id``):

1. candidates: label rows of the same make (spelling normalised), displacement within 0.05 L
   (the list gives 3 decimals, the labels 1), the same number of cylinders and the same
   gearbox: automatic (list A / SA; label "Automatic N-spd" / "(SN)" / "(AN)") and automated
   manual (AM / AMS; "(AMN)" / "(AM-SN)") and manual (M) with the same number of gears;
   continuously variable (CVT / SCV; "(variable gear ratios)" / "(AV-SN)" / "(A1)") any gears;
   the list's OT (other) any gearbox;
2. model name: the candidates whose model shares the list model's first word (after
   normalising case, hyphens and drive words) and, among them, the most shared words
   (Jaccard of the word sets without drive words);
3. drive: among those, the ones whose drive agrees with the list's (a drive word in the list's
   model name first, else its drive code; AWD / 4WD vehicles are often tested on a 2WD
   dynamometer and coded F or R) when any agree;
4. technology: where the candidates still differ by more than 0.5 %, the ones whose
   electrification (mild hybrid, hybrid) and start-stop agree with the technology classes
   `import-epa` attaches to the vehicle, when any agree;
5. matched when one label row is left, or several whose unrounded combined figures are within
   0.5 % of each other (their mean is used); "ambiguous" when several differ by more (listed,
   not used); "unmatched" with the step that left no candidate (listed, not used).

No number is fitted here. Electric and hydrogen vehicles are joined and listed like the others
(their labels are in MPGe); the validation uses only the vehicles with a liquid-fuel FTP.
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

LABELS = ROOT / "inputs" / "fueleconomy" / "vehicles_my2022.csv"
TSTCAR = ROOT / "inputs" / "epa" / "22-tstcar.csv"
#: label rows whose unrounded combined figures differ by less than this are one label
SAME_LABEL_REL = 0.005
DISPLACEMENT_TOL_L = 0.05
MAKE_ALIASES = {"mclaren automotive": "mclaren", "rolls royce": "rolls-royce", "bmx": "bmw",
                "range rover": "land rover", "polestar2 dual motor": "polestar"}
#: words that say the drive, not the model: word -> drive class ("4": AWD / 4WD, "2": two-wheel)
DRIVE_WORDS = {"AWD": "4", "4WD": "4", "4X4": "4", "XDRIVE": "4", "4MATIC": "4", "QUATTRO": "4",
               "ALL4": "4", "SHAWD": "4", "4MOTION": "4", "FWD": "2", "RWD": "2", "2WD": "2",
               "4X2": "2", "SDRIVE": "2"}
LABEL_DRIVE = {"Front-Wheel Drive": "F", "Rear-Wheel Drive": "R", "All-Wheel Drive": "A",
               "4-Wheel Drive": "4", "Part-time 4-Wheel Drive": "P", "4-Wheel or All-Wheel Drive": "A",
               "2-Wheel Drive": "2"}
#: the list's drive code -> label drive codes that agree with it
DRIVE_AGREES = {"F": "F2", "R": "R2", "A": "A4P", "4": "4PA", "P": "P4A"}
WORD_ALIASES = {"HYBRID": "HEV", "FHEV": "HEV"}
GEARBOX_OF_CODE = {"A": "auto", "SA": "auto", "AM": "am", "AMS": "am", "M": "manual",
                   "CVT": "cvt", "SCV": "cvt", "AV": "cvt", "AVS": "cvt", "OT": "any"}


def load_labels(path=LABELS) -> pd.DataFrame:
    """The shipped MY2022 label rows with the join keys: ``make_key``, ``gearbox``, ``gears``,
    ``drive_code``, ``words`` (model words without drive words) and ``label_drive`` (the
    drive said by a drive word of the model name, "" if none)."""
    d = pd.read_csv(path)
    d["make_key"] = d.make.map(_make_key)
    box = d.trany.map(_label_gearbox)
    d["gearbox"], d["gears"] = [b for b, _ in box], [g for _, g in box]
    d["drive_code"] = d.drive.map(LABEL_DRIVE).fillna("")
    d["words"] = [_words(m, k)[0] for m, k in zip(d.model, d.make)]
    return d


def _make_key(make) -> str:
    key = re.sub(r"\s+", " ", str(make).strip().lower())
    return MAKE_ALIASES.get(key, key)


def _label_gearbox(trany) -> tuple[str, float]:
    """(gearbox class, gears) of a label's ``trany`` ("Automatic (S8)", "Manual 6-spd", ...)."""
    t = str(trany)
    gears = re.search(r"(\d+)", t)
    n = float(gears.group(1)) if gears else np.nan
    if t.startswith("Manual"):
        return "manual", n
    if "variable" in t or "AV" in t or n == 1:
        return "cvt", n
    if "AM" in t:
        return "am", n
    return "auto", n


def _words(model, make="") -> tuple[tuple[str, ...], str]:
    """(model words without drive words, drive class said by a drive word or ""): upper case,
    hyphens inside a name dropped ("F-150" = "F150"), a short series name joined to its number
    ("C 300" = "C300", "RS 5" = "RS5"), the make's name in front dropped ("Ford Explorer",
    "MAZDA3"), "HYBRID" / "FHEV" = "HEV"."""
    text = re.sub(r"(?<=\w)-(?=\w)", "", str(model).upper()).replace("SH-AWD", "SHAWD")
    text = re.sub(r"\b([A-Z]{1,3}) (\d+)\b", r"\1\2", text)
    make_word = re.sub(r"[^A-Z0-9]", "", str(make).upper())
    words = [w for w in re.split(r"[^A-Z0-9]+", text) if w]
    if words and make_word and words[0].startswith(make_word) and len(words[0]) > len(make_word):
        words[0] = words[0][len(make_word):]
    elif len(words) > 1 and make_word and words[0] == make_word:
        words = words[1:]
    words = [WORD_ALIASES.get(w, w) for w in words]
    drive = next((DRIVE_WORDS[w] for w in words if w in DRIVE_WORDS), "")
    return tuple(w for w in words if w not in DRIVE_WORDS), drive


def list_vehicles(path=TSTCAR) -> pd.DataFrame:
    """One row per Test Car List vehicle (``vehicle_id``, as `import-epa` names it) with the
    join's columns, ``technology`` the classes `import-epa` attaches (NaN for the vehicles it
    does not import)."""
    from fleetrun.epa import import_test_car_list, read_test_car_list

    t = read_test_car_list(path)
    cols = ["manufacturer", "make", "model", "displacement_L", "cylinders", "transmission_code", "gears",
            "drive_code", "fuel_description"]
    out = t.groupby("vehicle_id", sort=False)[cols].first().reset_index()
    tech = {v["vehicle_id"]: v.get("technology") for v in import_test_car_list(path).vehicles}
    out["technology"] = out.vehicle_id.map(tech)
    return out


def join(vehicles: pd.DataFrame, labels: pd.DataFrame) -> pd.DataFrame:
    """Per list vehicle: ``status`` (matched / ambiguous / unmatched), ``reason``, the label ids
    and models used, ``comb08U`` (mean of the matched rows' unrounded combined mpg), ``comb08``
    (printed whole mpg), ``UCity`` / ``UHighway`` (the label's unadjusted city and highway
    mpg), ``n_candidates`` and ``spread`` (max / min - 1 of the candidates' comb08U)."""
    by_make = {k: g for k, g in labels.groupby("make_key")}
    return pd.DataFrame([_join_one(v, by_make, labels) for v in vehicles.itertuples(index=False)])


def _join_one(v, by_make, labels) -> dict:
    out = dict(vehicle_id=v.vehicle_id, make=v.make, model=v.model, status="unmatched", reason="",
               label_ids="", label_models="", comb08U=np.nan, comb08=np.nan, UCity=np.nan, UHighway=np.nan,
               n_candidates=0, spread=np.nan, drive_agrees=False, candidates_comb08U=np.nan)
    same = by_make.get(_make_key(v.make))
    c, reason = _engine_candidates(v, same) if same is not None else (None, "make not in the labels")
    words, drive_word = _words(v.model, v.make)
    if c is not None:
        c = c[[_same_model(words, w) for w in c.words]]
        if c.empty:
            c, reason = None, "engine and gearbox match only other models"
    if c is None:       # another make of the group (Lexus tested as TOYOTA, Supra as BMW, ...)
        other, _ = _engine_candidates(v, labels)
        other = None if other is None else other[[_same_model(words, w) for w in other.words]]
        if other is None or other.empty:
            return {**out, "reason": reason}
        c = other
        out["reason"] = f"label make {'/'.join(sorted(set(c.make)))}; "
    score = np.array([len(set(words) & set(w)) / len(set(words) | set(w)) for w in c.words])
    c = c[score == score.max()]
    agrees = c.drive_code.map(lambda d: _drive_agrees(d, drive_word, v.drive_code)).to_numpy()
    if agrees.any():
        c = c[agrees]
    c, by_technology = _technology_agrees(c, getattr(v, "technology", None))
    if by_technology:
        out["reason"] += "technology classes chose; "
    spread = c.comb08U.max() / c.comb08U.min() - 1.0
    out.update(label_ids=" ".join(map(str, c.id)), label_models=" | ".join(sorted(set(c.model))),
               n_candidates=len(c), spread=spread, drive_agrees=bool(agrees.any()),
               candidates_comb08U=c.comb08U.mean())
    if spread > SAME_LABEL_REL:
        return {**out, "status": "ambiguous", "reason": out["reason"] + f"{len(c)} labels differing by {spread:.1%}"}
    return {**out, "status": "matched", "comb08U": c.comb08U.mean(), "comb08": c.comb08.mean(),
            "UCity": c.UCity.mean(), "UHighway": c.UHighway.mean(),
            "reason": out["reason"] + ("one label" if len(c) == 1 else f"{len(c)} labels within {SAME_LABEL_REL:.1%}")}


def _engine_candidates(v, c):
    """(label rows with the list vehicle's displacement, cylinders and gearbox, None if none;
    the step that left none)."""
    c = c[(c.displ - v.displacement_L).abs() < DISPLACEMENT_TOL_L]
    if c.empty:
        return None, "no label of this make with this displacement"
    if np.isfinite(v.cylinders):
        c = c[c.cylinders == v.cylinders]
        if c.empty:
            return None, "no label with these cylinders"
    c = c[_gearbox_agrees(c, v)]
    if c.empty:
        return None, "no label with this gearbox and gears"
    return c, ""


def _same_model(words, label_words) -> bool:
    """The list's first model word is one of the label's, or the label's first one of the list's."""
    return bool(words) and bool(label_words) and (words[0] in label_words or label_words[0] in words)


def _technology_agrees(c, technology) -> tuple[pd.DataFrame, bool]:
    """Step 5: where the candidates differ by more than SAME_LABEL_REL and in electrification
    (label: "Mild Hybrid" in ``eng_dscr``, else atvType "Hybrid") or start-stop (``startStop``),
    keep the ones that agree with the vehicle's technology classes as `import-epa` attaches them
    (mild_hybrid_48v, p2_hybrid, start_stop; "none": no class; docs/epa-import.md "Technology
    classes"), if any. Not a string (the importer found no class source): nothing chosen."""
    if len(c) < 2 or c.comb08U.max() / c.comb08U.min() - 1.0 <= SAME_LABEL_REL or not isinstance(technology, str):
        return c, False
    names = set(technology.split(","))
    electric = "mhev" if "mild_hybrid_48v" in names else "hev" if "p2_hybrid" in names else ""
    label_electric = np.where(c.eng_dscr.fillna("").str.contains("Mild Hybrid"), "mhev",
                              np.where(c.atvType.fillna("") == "Hybrid", "hev", ""))
    keep = c
    if len(set(label_electric)) > 1 and (label_electric == electric).any():
        keep = c[label_electric == electric]
    stop = keep.startStop.fillna("N").eq("Y").to_numpy()
    if len(set(stop)) > 1 and (stop == ("start_stop" in names or electric != "")).any():
        keep = keep[stop == ("start_stop" in names or electric != "")]
    return keep, len(keep) < len(c)


def _gearbox_agrees(c, v):
    """Gearbox rule of the join; the list's and the labels' codes for automatics and automated
    manuals are not used consistently (list "A" 8 = label "(AM8)"), so both are one class."""
    box = "cvt" if v.gears == 1 else GEARBOX_OF_CODE.get(v.transmission_code, "any")
    if box == "any":
        return np.ones(len(c), bool)
    if box == "cvt":
        return (c.gearbox == "cvt").to_numpy()
    stepped = c.gearbox.isin(["auto", "am"]) if box in ("auto", "am") else c.gearbox == box
    return (stepped & (c.gears == v.gears)).to_numpy()


def _drive_agrees(label_drive, drive_word, list_code) -> bool:
    if drive_word == "4":
        return label_drive in "A4P"
    if drive_word == "2":
        return label_drive in "FR2"
    return label_drive in DRIVE_AGREES.get(list_code, "")


def joined(path_list=TSTCAR, path_labels=LABELS) -> pd.DataFrame:
    """The join of the whole list (see :func:`join`)."""
    return join(list_vehicles(path_list), load_labels(path_labels))


def labels_of(r, table, j):
    """Per vehicle of ``r["err"]`` (epa_one_number.prepare): the join's columns (NaN / "" where
    the vehicle is not in it) and ``used`` (matched, with a liquid-fuel FTP and HWFET)."""
    idx = r["err"].index
    out = j.set_index("vehicle_id").reindex(table.vehicle_id.to_numpy()[idx])
    out.index = idx
    paired = r["paired"]
    out["used"] = ((out.status == "matched").to_numpy() & np.isfinite(out.comb08U.to_numpy())
                   & np.isfinite(paired["FTP"].to_numpy()[idx]) & np.isfinite(paired["HWFET"].to_numpy()[idx]))
    return out


def distribution(x) -> str:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    q = np.quantile(x, [0.05, 0.25, 0.5, 0.75, 0.95])
    return (f"n={x.size} median {q[2]:+.2%} (25-75 % {q[1]:+.2%}..{q[3]:+.2%}, 5-95 % {q[0]:+.2%}..{q[4]:+.2%}), "
            f"mean {x.mean():+.2%}; within 0.5 / 1 / 2 / 5 %: "
            + " / ".join(f"{np.mean(np.abs(x) <= t):.1%}" for t in (0.005, 0.01, 0.02, 0.05)))


FORMULA_TABLES = ("derived_2008", "derived_2017")   # models/budget.toml [onroad.epa_label.sets]


def label_formula_check(labels, table) -> dict:
    """EPA's derived label formulas (the coefficient set ``table``, fleetrun.physics.epa_label)
    applied to each label row's own unadjusted city and highway figures (UCity, UHighway)
    against its unrounded label figures, liquid-fuel rows whose figure is not a whole number
    (where it is, only the rounded value is published): per figure, relative differences."""
    from fleetrun.physics import epa_label

    coef = epa_label.label_set(table)
    d = labels[~labels.atvType.isin(["EV", "Plug-in Hybrid"]) & (labels.UCity > 0) & (labels.UHighway > 0)]
    city = 1.0 / epa_label.label_gal_per_mile(1.0 / d.UCity.to_numpy(), *coef.city)
    hw = 1.0 / epa_label.label_gal_per_mile(1.0 / d.UHighway.to_numpy(), *coef.highway)
    comb = epa_label.combined_label_mpg(d.UCity.to_numpy(), d.UHighway.to_numpy(), coef)
    out = {}
    for col, x in (("city08U", city), ("highway08U", hw), ("comb08U", comb)):
        real = d[col].to_numpy()
        keep = ~np.isclose(real, np.round(real), atol=1e-4)
        out[col] = (np.asarray(x) / real - 1.0)[keep]
    return out


def formula_lines(r, lab, labels) -> list[str]:
    """Do the derived-label formulas (models/budget.toml) give the MY2022 labels? From each
    label's own unadjusted figures (all MY2022 labels) and, on the joined vehicles, the derived
    combined figure of the list's measured FTP and HWFET against the real comb08U."""
    from epa_one_number import derived_label

    lines = []
    for table in FORMULA_TABLES:
        for col, e in label_formula_check(labels, table).items():
            lines.append(f"[{table}] of UCity/UHighway vs {col}: within 0.01 % {np.mean(np.abs(e) <= 1e-4):.1%}; "
                         + distribution(e))
    used = lab.used.to_numpy()
    real = lab.comb08U.to_numpy()[used]
    for table in FORMULA_TABLES:
        of_list = derived_label(r["paired"], lab.index[used], table)
        lines.append(f"[{table}] derived label of the list's FTP and HWFET / real comb08U - 1: "
                     + distribution(of_list / real - 1))
    return lines


def route_lines(r, lab) -> tuple[list[str], dict]:
    """The label route of epa_one_number.py (L1: k on FTP and HWFET so that the label is exact,
    k^s on US06), s the stored share and s fitted held out (22 and 5 manufacturer folds), with the
    derived label, the real unrounded label and the real label as printed, on the joined vehicles."""
    from epa_one_number import SHARE_GRID, describe, derived_label, fit_held_out, gallons_line, label_errors
    from fleet_error import folds_of

    from fleetrun.simulation import measured

    used = lab.used.to_numpy()
    err, mf = r["err"], r["manufacturer"]
    five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
    real, printed = (np.where(used, lab[c].to_numpy(), np.nan) for c in ("comb08U", "comb08"))
    variants = {"derived (MY2017 formulas)": (np.where(used, derived_label(r["paired"], err.index), np.nan), None),
                "real comb08U, 2008 formulas": (real, "derived_2008"),
                "real comb08 (whole mpg), 2008 formulas": (printed, "derived_2008"),
                "real comb08U": (real, None), "real comb08 (whole mpg)": (printed, None),
                "real comb08U + ambiguous (candidates' mean)": (
                    np.where(used, real, np.where(lab.status.to_numpy() == "ambiguous",
                                                  lab.candidates_comb08U.to_numpy(), np.nan)), None)}
    lines, results = [f"{used.sum()} of {len(err)} vehicles joined to one label"], {}
    lines.append("physics + technology alone on them: " + describe(err.loc[used], TESTS_ALL))
    for name, (label, table) in variants.items():
        e = label_errors(r, "share", measured.transfer_share(), label=label, table=table)
        results[(name, "stored")] = e
        lines.append(f"{name}, stored s {measured.transfer_share()}: {describe(e, TESTS_ALL)}")
        for split_name, groups in (("22 folds", mf), ("5 folds", five)):
            family = dict(grid=SHARE_GRID, apply=lambda s, x=label, t=table: label_errors(r, "share", s, label=x, table=t))
            e, chosen = fit_held_out(err, groups, family)
            results[(name, split_name)] = e
            lines.append(f"{name}, s fitted held out [{split_name}]: {describe(e, TESTS_ALL)}; s over folds "
                         f"{min(chosen.values())}..{max(chosen.values())}")
        lines.append(f"     {gallons_line(results[(name, '22 folds')], r['paired'])}")
    lines += split_lines(r, lab, results[("real comb08U", "22 folds")])
    return lines, results


def split_lines(r, lab, e) -> list[str]:
    """The held-out errors of the real label split by how close the label is to the vehicle's
    own tests: |derived label (MY2017 formulas) of the list's FTP and HWFET / comb08U - 1| up
    to 0.5 % (the label is, in effect, this test vehicle's) or more (other configurations,
    5-cycle testing, another test vehicle)."""
    from epa_one_number import describe, derived_label

    used = lab.used.to_numpy()
    gap = np.abs(derived_label(r["paired"], lab.index) / lab.comb08U.to_numpy() - 1.0)
    lines = []
    for name, rows in (("label within 0.5 % of the vehicle's own derived label", used & (gap <= 0.005)),
                       ("label further from it", used & (gap > 0.005))):
        lines.append(f"  {name}: {describe(e.loc[rows], TESTS_ALL)}")
    return lines


TESTS_ALL = ("FTP", "HWFET", "US06")


def group_label_errors(r, share, label, groups):
    """Pre-registered rule G1 (docs/validation-epa.md "Several test vehicles on one label"): the
    vehicles joined to the same label (``groups``: the same ``label_ids``) share one fuel scale
    k_g so that the equal-weight mean over the group of each vehicle's label fuel per mile (its
    simulated FTP and HWFET divided by k_g, the derived formulas of the list's model year) is
    1 / label: the label is the model type's sales-weighted mean in fuel per mile (40 CFR
    600.208-12, 600.210-12(c)); sales are unknown here, so equal weights; the simulation carries
    each configuration's difference (weight, road load, N/V) from the group's mean. FTP and
    HWFET scaled by k_g, US06 by k_g^share (``measured.label_scale`` with ``groups``, as the
    Vehicles column ``label_group`` does). A vehicle alone on its label: the per-vehicle route.
    Rows without a label or group: NaN."""
    from epa_one_number import TESTS, label_set

    from fleetrun.simulation import measured

    err, paired = r["err"], r["paired"]
    idx = err.index
    meas = np.c_[paired["FTP"].to_numpy()[idx], paired["HWFET"].to_numpy()[idx]]
    pred = meas * (1.0 + err[["FTP", "HWFET"]].to_numpy())
    label = np.asarray(label, float)
    ok = np.isfinite(label) & np.isfinite(pred).all(axis=1) & pd.notna(pd.Series(groups)).to_numpy()
    k = measured.label_scale(np.where(ok, label, np.nan), pred[:, 0], pred[:, 1], label_set=label_set(None),
                             groups=groups)
    scale = np.c_[k, k, k ** share]
    out = pd.DataFrame((1.0 + err[list(TESTS)].to_numpy()) / scale - 1.0, index=idx, columns=list(TESTS))
    out.loc[~ok, :] = np.nan
    return out


def highway_label_errors(r, share, highway_label, groups=None):
    """Pre-registered rule H1 (H1g with ``groups``; docs/validation-epa.md "Several test vehicles
    on one label"): the label's highway figure (highway08U) as the one number. The vehicle's fuel
    scale k_H makes the highway formula (the list's model year) of its simulated HWFET / k_H give
    the label's highway figure; with ``groups``, the vehicles on one label share k_H (the group's
    mean highway fuel per mile). HWFET scaled by k_H, FTP and US06 by k_H^share."""
    from epa_one_number import TESTS, label_set

    err, paired = r["err"], r["paired"]
    idx = err.index
    a, b = label_set(None).highway
    pred = paired["HWFET"].to_numpy()[idx] * (1.0 + err["HWFET"].to_numpy())
    slope = b / pred                                          # 1/label = a + k_H slope
    hl = np.asarray(highway_label, float)
    ok = np.isfinite(hl) & np.isfinite(slope)
    if groups is not None:
        ok &= pd.notna(pd.Series(groups)).to_numpy()
        key = pd.Series(np.where(ok, groups, None), index=idx)
        slope = pd.Series(np.where(ok, slope, np.nan), index=idx).groupby(key).transform("mean").to_numpy()
    k = (1.0 / hl - a) / slope
    scale = np.c_[k ** share, k, k ** share]
    out = pd.DataFrame((1.0 + err[list(TESTS)].to_numpy()) / scale - 1.0, index=idx, columns=list(TESTS))
    out.loc[~ok, :] = np.nan
    return out


def fit_other_tests(err, folds, family):
    """Per held-out fold: the share minimising the FTP and US06 squared log errors of the other
    folds (the HWFET is the calibration's own test); held-out errors and the fold values."""
    tables = [(s, family(s)) for s in SHARE_GRID_H]
    out, chosen = err * np.nan, []
    for g in np.unique(folds):
        train = folds != g
        s, t = min(tables, key=lambda st: float(np.nansum(np.log1p(st[1].loc[train, ["FTP", "US06"]].to_numpy()) ** 2)))
        chosen.append(s)
        out.loc[~train] = t.loc[~train]
    return out, chosen


SHARE_GRID_H = tuple(np.round(np.arange(0.0, 1.51, 0.05), 2))


def highway_figure(lab) -> np.ndarray:
    """The unrounded highway label figure (highway08U) per vehicle of ``lab``: the mean over its
    matched label rows (as the join's comb08U), NaN without labels."""
    by_id = load_labels().set_index("id").highway08U
    ids = lab.label_ids.fillna("").astype(str)
    return np.array([np.mean([by_id[int(i)] for i in x.split()]) if x.strip() else np.nan for x in ids])


def highway_lines(r, lab) -> list[str]:
    """H1 and H1g held out (22 and 5 manufacturer folds) on the joined vehicles, real unrounded
    highway08U."""
    from epa_one_number import describe
    from fleet_error import folds_of

    used = lab.used.to_numpy()
    err, mf = r["err"], r["manufacturer"]
    five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
    hl = np.where(used, highway_figure(lab), np.nan)
    groups = np.where(used, lab.label_ids.astype(str).to_numpy(), None)
    lines = []
    for name, g in (("H1 highway label, per vehicle", None), ("H1g highway label, group scale", groups)):
        for split_name, folds in (("22 folds", mf), ("5 folds", five)):
            e, chosen = fit_other_tests(err, folds, lambda s, g=g: highway_label_errors(r, s, hl, g))
            lines.append(f"{name} [{split_name}]: {describe(e, TESTS_ALL)}; s {min(chosen)}..{max(chosen)}")
    return lines


def group_lines(r, lab) -> list[str]:
    """G1 against the per-vehicle route on the same vehicles (real unrounded comb08U, the
    formulas of the list's model year), the share fitted held out (22 and 5 manufacturer folds);
    split into vehicles alone on their label and vehicles sharing it. And the diagnostic D1:
    how often the vehicle's measured HWFET is within 5 % of its label's own unadjusted highway
    figure (UHighway, the model type's HWFET the label formula starts from)."""
    from epa_one_number import SHARE_GRID, describe, fit_held_out, label_errors
    from fleet_error import folds_of

    used = lab.used.to_numpy()
    err, mf = r["err"], r["manufacturer"]
    five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
    real = np.where(used, lab.comb08U.to_numpy(), np.nan)
    groups = np.where(used, lab.label_ids.astype(str).to_numpy(), None)
    size = pd.Series(groups).map(pd.Series(groups).value_counts()).to_numpy()
    shared = used & (size >= 2)
    lines = [f"G1: {shared.sum()} of {used.sum()} vehicles share their label with another list vehicle "
             f"({pd.Series(groups[shared]).nunique()} labels)"]
    for name, apply in (("per vehicle (L1)", lambda s: label_errors(r, "share", s, label=real)),
                        ("G1 group scale", lambda s: group_label_errors(r, s, real, groups))):
        for split_name, folds in (("22 folds", mf), ("5 folds", five)):
            e, chosen = fit_held_out(err, folds, dict(grid=SHARE_GRID, apply=apply))
            lines.append(f"{name} [{split_name}]: {describe(e, TESTS_ALL)}; s {min(chosen.values())}.."
                         f"{max(chosen.values())}")
            if split_name == "22 folds":
                for part, rows in (("  alone on its label", used & ~shared), ("  sharing its label", shared)):
                    lines.append(f"{part}: {describe(e.loc[rows], TESTS_ALL)}")
    hw = r["paired"]["HWFET"].to_numpy()[err.index]
    d1 = hw / lab.UHighway.to_numpy() - 1.0
    lines.append("D1 measured HWFET / the label's UHighway - 1 (joined vehicles): " + distribution(d1[used]))
    lines.append("D1 sharing a label: " + distribution(d1[shared]) + " | alone: " + distribution(d1[used & ~shared]))
    return lines


def prepared():
    """epa_one_number.prepare of the list, with the list's table."""
    from epa_one_number import TESTS, prepare
    from epa_table import epa_fleet

    specs, table = epa_fleet()
    r = prepare(specs, table)
    r["err"] = r["err"][list(TESTS)]
    return r, table


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--list", help="write the per-vehicle join (CSV) here")
    ap.add_argument("--join-only", action="store_true", help="the join alone (no simulation)")
    ap.add_argument("--groups", action="store_true", help="only the pre-registered group rule G1 and D1")
    args = ap.parse_args(argv)
    j = joined()
    print(f"{len(j)} list vehicles: " + ", ".join(f"{k} {n}" for k, n in j.status.value_counts().items()))
    print("unmatched, by the step that left no label: "
          + ", ".join(f"{k} {n}" for k, n in j[j.status == "unmatched"].reason.value_counts().items()))
    print("ambiguous, spread of the candidates' comb08U: " + distribution(j[j.status == "ambiguous"].spread))
    if args.list:
        j.to_csv(args.list, index=False)
    if args.join_only:
        return
    r, table = prepared()
    lab = labels_of(r, table, j)
    print(f"vehicles of the validation (pairs merged): {len(lab)}; " + ", ".join(
        f"{k} {n}" for k, n in lab.status.fillna("not in the list").value_counts().items()))
    if args.groups:
        for text in group_lines(r, lab) + highway_lines(r, lab):
            print(text, flush=True)
        return
    lines, _ = route_lines(r, lab)
    for text in formula_lines(r, lab, load_labels()) + lines:
        print(text, flush=True)


if __name__ == "__main__":
    main()
