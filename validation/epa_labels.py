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
4. matched when one label row is left, or several whose unrounded combined figures are within
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
    join's columns."""
    from fleetrun.epa import read_test_car_list

    t = read_test_car_list(path)
    cols = ["manufacturer", "make", "model", "displacement_L", "cylinders", "transmission_code", "gears",
            "drive_code", "fuel_description"]
    return t.groupby("vehicle_id", sort=False)[cols].first().reset_index()


def join(vehicles: pd.DataFrame, labels: pd.DataFrame) -> pd.DataFrame:
    """Per list vehicle: ``status`` (matched / ambiguous / unmatched), ``reason``, the label ids
    and models used, ``comb08U`` (mean of the matched rows' unrounded combined mpg), ``comb08``
    (printed whole mpg), ``UCity`` / ``UHighway`` (the label's unadjusted city and highway
    mpg), ``n_candidates`` and ``spread`` (max / min - 1 of the candidates' comb08U)."""
    by_make = {k: g for k, g in labels.groupby("make_key")}
    return pd.DataFrame([_join_one(v, by_make) for v in vehicles.itertuples(index=False)])


def _join_one(v, by_make) -> dict:
    out = dict(vehicle_id=v.vehicle_id, make=v.make, model=v.model, status="unmatched", reason="",
               label_ids="", label_models="", comb08U=np.nan, comb08=np.nan, UCity=np.nan, UHighway=np.nan,
               n_candidates=0, spread=np.nan, drive_agrees=False)
    same = by_make.get(_make_key(v.make))
    c, reason = _engine_candidates(v, same) if same is not None else (None, "make not in the labels")
    words, drive_word = _words(v.model, v.make)
    if c is not None:
        c = c[[_same_model(words, w) for w in c.words]]
        if c.empty:
            c, reason = None, "engine and gearbox match only other models"
    if c is None:       # another make of the group (Lexus tested as TOYOTA, Supra as BMW, ...)
        other, _ = _engine_candidates(v, pd.concat(by_make.values()))
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
    spread = c.comb08U.max() / c.comb08U.min() - 1.0
    out.update(label_ids=" ".join(map(str, c.id)), label_models=" | ".join(sorted(set(c.model))),
               n_candidates=len(c), spread=spread, drive_agrees=bool(agrees.any()))
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--list", help="write the per-vehicle join (CSV) here")
    args = ap.parse_args(argv)
    j = joined()
    print(f"{len(j)} list vehicles: " + ", ".join(f"{k} {n}" for k, n in j.status.value_counts().items()))
    print(j[j.status == "unmatched"].reason.value_counts().to_string())
    if args.list:
        j.to_csv(args.list, index=False)


if __name__ == "__main__":
    main()
