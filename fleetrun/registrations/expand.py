"""Registration rows -> simulated vehicle cohorts, their counts and miles per budget year.

A cohort is one representing vehicle (library, EPA Test Car List or Vehicles row) x FHWA class
x fuel x model year (x a row's own annual miles). Registration rows that fall on the same
cohort are added up, so an extract of 50,000 make/model/year rows simulates each distinct
vehicle once and reports a few thousand cohorts. Every row is listed in :attr:`Expansion.choices`
(which vehicle, matched on what, assumed what); a row nothing represents is listed with its
count and a warning, never dropped silently. Arithmetic: docs/registrations.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from fleetrun.errors import InputError
from fleetrun.registrations import library as lib
from fleetrun.registrations import turnover
from fleetrun.vehicle import VehicleSpec
from fleetrun.workbook.reader import own_year1_miles

CHOICE_COLUMNS = ["registration_row", "vehicle_class", "fhwa_class", "fuel", "count", "model_year",
                  "vehicle", "matched_on", "assumed"]
NOT_MODELLED = "not modelled"


@dataclass
class Expansion:
    vehicles: list[VehicleSpec]
    fhwa_class: np.ndarray            # per cohort
    model_year: np.ndarray            # per cohort (int)
    reference_year: np.ndarray        # model year of the representing vehicle (trend reference)
    counts: np.ndarray                # (cohorts, horizon): vehicles per year offset from the base year
    miles_per_vehicle: np.ndarray     # (cohorts, horizon)
    base_year: int
    choices: pd.DataFrame
    warnings: list[str] = field(default_factory=list)

    def offset(self, scenario) -> int:
        first = scenario.first_fiscal_year
        return 0 if first is None else int(first) - self.base_year

    def year_miles(self, scenario, other_year1_miles: float = 0.0) -> np.ndarray:
        """(cohorts, budget years) miles: turnover's composition, the fleet's total scaled to
        ``base_year_vmt_million`` (less the Vehicles rows' miles) in year 1 and grown by
        ``vmt_growth_pct_per_year`` after it; each class named in ``base_year_vmt_share_pct``
        drives its percent of that total every year, the other classes share the rest in
        proportion to their own miles (docs/registrations.md, "Miles by class")."""
        k0, years = self.offset(scenario), scenario.budget_years
        raw = self.counts[:, k0:k0 + years] * self.miles_per_vehicle[:, k0:k0 + years]
        totals = raw.sum(axis=0)
        if scenario.base_year_vmt_million is not None:
            target = scenario.base_year_vmt_million * 1e6 - other_year1_miles
            if target <= 0:   # the reader refuses this first (reader._check_base_vmt); never negative miles
                raise InputError(f"scenario {scenario.scenario_id}: base_year_vmt_million is not more than the "
                                 "Vehicles rows' own miles", hint="give the whole fleet's vehicle-miles")
        else:
            target = totals[0]
        g = scenario.vmt_growth_pct_per_year / 100.0
        wanted = target * (1.0 + g) ** np.arange(years)
        groups = self.share_groups(scenario)
        out = np.zeros_like(raw)
        for rows, share in groups:
            have = raw[rows].sum(axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                out[rows] = raw[rows] * np.where(have > 0, share * wanted / have, 0.0)
        return out

    def share_groups(self, scenario) -> list[tuple[np.ndarray, float]]:
        """[(cohort rows, share of the miles)]: one group per class of ``base_year_vmt_share_pct``,
        one for every other class (the rest). A class given a share but without a vehicle is
        an InputError (its miles would vanish)."""
        shares = scenario.base_year_vmt_share_pct or {}
        groups, listed = [], np.zeros(len(self.fhwa_class), dtype=bool)
        for name, pct in shares.items():
            rows = self.fhwa_class == name
            if pct > 0 and not rows.any():
                raise InputError(f"scenario {scenario.scenario_id}: base_year_vmt_share_pct gives {name} "
                                 f"{pct:g} % of the miles, but the Registrations sheet has no {name} "
                                 f"(nor a truck row split into it)",
                                 hint="add its registrations, or drop it from base_year_vmt_share_pct")
            groups.append((rows, pct / 100.0))
            listed |= rows
        rest = 1.0 - sum(pct for pct in shares.values()) / 100.0
        if shares and rest > 1e-9 and listed.all():
            raise InputError(f"scenario {scenario.scenario_id}: base_year_vmt_share_pct adds up to "
                             f"{100 * (1 - rest):g} %, and every class with registrations is listed",
                             hint="the listed percents must add up to 100 when no other class is registered")
        groups.append((~listed, rest))
        return groups

    def fuel_factor(self, scenario) -> np.ndarray:
        """Fuel per mile of each cohort's model year relative to its representing vehicle."""
        rate = scenario.new_vehicle_mpg_change_pct_per_year
        rate = None if rate is None else rate / 100.0
        out = np.ones(len(self.vehicles))
        for name in set(self.fhwa_class.tolist()):
            rows = self.fhwa_class == name
            out[rows] = turnover.fuel_factor(name, self.model_year[rows], self.reference_year[rows], rate)
        return out


def base_year(scenarios) -> int:
    """The calendar year the registrations describe: the earliest first fiscal year."""
    firsts = [int(s.first_fiscal_year) for s in scenarios if s.first_fiscal_year is not None]
    return min(firsts) if firsts else int(turnover.constants()["default_base_year"])


def horizon(scenarios, base: int) -> int:
    return max([1] + [((s.first_fiscal_year or base) - base) + s.budget_years for s in scenarios])


class _Cohorts:
    """Counts by cohort key, the representing vehicles and the choices listed."""

    def __init__(self, base: int, fleet_vehicles: dict[str, VehicleSpec]):
        self.base = base
        self.counts: dict[tuple, float] = {}
        self.reps: dict[str, object] = {}
        self.choices: list[dict] = []
        self.fleet_vehicles = fleet_vehicles
        self.unmodelled = 0.0
        self.new_sales: dict[tuple, float] = {}   # cohort key -> vehicles sold in its model year

    def add(self, rep_key, rep, fhwa_class, fuel, model_year, miles, count):
        self.reps.setdefault(rep_key, rep)
        key = (rep_key, fhwa_class, fuel, int(model_year), miles)
        self.counts[key] = self.counts.get(key, 0.0) + count


def _classes(row: dict) -> list[tuple[str, float, str]]:
    """(FHWA class, share, note): MV-1's ``truck`` split by the documented shares."""
    if row["vehicle_class"] != "truck":
        return [(row["vehicle_class"], 1.0, "")]
    split = turnover.constants()["truck_split"]
    return [(name, float(share), f"truck split {float(share):.1%} (models/turnover.toml [truck_split])")
            for name, share in split.items()]


def _fuels(row: dict, fhwa_class: str) -> list[tuple[str, float, str]]:
    if row.get("fuel"):
        return [(row["fuel"], 1.0, "")]
    split = turnover.class_info(fhwa_class)["fuel_split"]
    return [(fuel, float(share), f"fuel split {float(share):.1%}") for fuel, share in split.items()]


def _model_years(row: dict, fhwa_class: str, base: int) -> tuple[np.ndarray, np.ndarray, str]:
    if row.get("model_year") is not None:
        return np.array([int(row["model_year"])]), np.array([1.0]), ""
    shares = turnover.age_distribution(fhwa_class)
    return base - np.arange(len(shares)), shares, "default age distribution (steady state of the survival curve)"


def _representatives(row: dict, fhwa_class: str, fuel: str, acc: _Cohorts):
    """[(rep_key, rep, share)], the vehicle text, matched on, assumed."""
    vid = row.get("vehicle_id")
    if vid:
        return [(f"VEH:{vid}", acc.fleet_vehicles[vid], 1.0)], vid, "vehicle_id", ""
    if row.get("make") and row.get("model"):
        found, note = lib.match_make_model(str(row["make"]), str(row["model"]), fuel)
        if found:
            share = 1.0 / len(found)
            text = ", ".join(v.library_id for v in found[:5]) + (" ..." if len(found) > 5 else "")
            return [(v.library_id, v, share) for v in found], text, note, ""
        assumed = f"make/model {row['make']} {row['model']} not in the EPA 2022 Test Car List; class default"
    elif row.get("make") or row.get("model"):
        assumed = "make or model alone is not matched; class default"
    else:
        assumed = ""
    mix, borrowed = lib.class_mix(fhwa_class, fuel)
    assumed = "; ".join(t for t in (assumed, borrowed) if t)
    if not mix:
        return [], NOT_MODELLED, "", assumed
    text = f"default {fhwa_class} {fuel} mix: " + ", ".join(f"{v.library_id} {s:.0%}" for v, s in mix)
    return [(v.library_id, v, s) for v, s in mix], text, "vehicle_class + fuel", assumed


def allocate(row: dict, acc: _Cohorts, label) -> None:
    """Add one registration row's vehicles to the cohorts and list the choices made."""
    miles = row.get("annual_miles")
    for fhwa_class, class_share, class_note in _classes(row):
        for fuel, fuel_share, fuel_note in _fuels(row, fhwa_class):
            years, year_shares, year_note = _model_years(row, fhwa_class, acc.base)
            count = float(row["count"]) * class_share * fuel_share
            reps, text, matched, assumed = _representatives(row, fhwa_class, fuel, acc)
            notes = "; ".join(t for t in (class_note, fuel_note, year_note, assumed) if t)
            acc.choices.append({"registration_row": label, "vehicle_class": row["vehicle_class"],
                                "fhwa_class": fhwa_class, "fuel": fuel, "count": count,
                                "model_year": row.get("model_year") if row.get("model_year") is not None
                                else "age distribution", "vehicle": text, "matched_on": matched, "assumed": notes})
            if not reps:
                acc.unmodelled += count
                continue
            for rep_key, rep, share in reps:
                for my, ys in zip(years.tolist(), year_shares.tolist()):
                    if ys > 0:
                        acc.add(rep_key, rep, fhwa_class, fuel, my, miles, count * share * ys)


def _spec(rep, rep_key: str, cache: dict, path) -> VehicleSpec:
    if rep_key not in cache:
        if isinstance(rep, VehicleSpec):
            cache[rep_key] = rep
        else:
            from fleetrun.workbook.vehicle_file import vehicle_from_mapping

            cache[rep_key] = vehicle_from_mapping({**dict(rep.row), "vehicle_id": rep_key, "vehicle_class": "x",
                                                   "count": 1, "annual_miles": 1}, path)
    return cache[rep_key]


def _reference_year(rep, my: int) -> float:
    ref = rep.model_year if not isinstance(rep, VehicleSpec) else rep.model_year
    if ref is None:
        ref = turnover.constants()["library_model_year"] if not isinstance(rep, VehicleSpec) else my
    return float(ref)


def build(acc: _Cohorts, scenarios, path=None) -> Expansion:
    """Cohort arrays over the horizon, with each class and fuel's scrapped vehicles replaced
    by new model years of the class's default mix."""
    base = acc.base
    h = horizon(scenarios, base)
    keys = list(acc.counts)
    counts0 = np.array([acc.counts[k] for k in keys])
    _new_sales(acc, keys, counts0, h)
    return _arrays(acc, h, path)


def _cohort_counts(classes, ages0, counts0, h) -> np.ndarray:
    out = np.zeros((len(classes), h))
    k = np.arange(h)
    for name in set(classes):
        rows = np.array([c == name for c in classes])
        ages = ages0[rows]
        s0 = turnover.survival_at(name, ages)
        later = turnover.survival_at(name, ages[:, None] + k[None, :])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(s0[:, None] > 0, later / s0[:, None], (k[None, :] == 0).astype(float))
        out[rows] = counts0[rows, None] * ratio
    return out


def _shifted_survival(fhwa_class: str, h: int, j: int) -> np.ndarray:
    """S(k - j) over k = 0..h-1 (0 before year j): a cohort sold in year j."""
    survival = turnover.survival(fhwa_class)
    ages = np.arange(h) - j
    return np.where(ages >= 0, survival[np.clip(ages, 0, len(survival) - 1)], 0.0)


def _new_sales(acc: _Cohorts, keys: list, counts0: np.ndarray, h: int) -> None:
    """New model years base+1 .. base+h-1 per class and fuel: as many as keep the class and
    fuel's stock at its base-year count (the vehicles scrapped are replaced)."""
    base = acc.base
    ages0 = np.array([max(base - k[3], 0) for k in keys])
    stock = _cohort_counts([k[1] for k in keys], ages0, counts0, h)
    groups: dict[tuple, np.ndarray] = {}
    for i, k in enumerate(keys):
        groups[(k[1], k[2])] = groups.get((k[1], k[2]), np.zeros(h)) + stock[i]
    for (fhwa_class, fuel), total in groups.items():
        mix, assumed = lib.class_mix(fhwa_class, fuel)
        if not mix:
            continue
        kept = total.copy()
        for j in range(1, h):
            sold = max(total[0] - kept[j], 0.0)
            if sold <= 0:
                continue
            kept = kept + sold * _shifted_survival(fhwa_class, h, j)
            for v, share in mix:
                acc.add(v.library_id, v, fhwa_class, fuel, base + j, None, 0.0)
                key = (v.library_id, fhwa_class, fuel, base + j, None)
                acc.new_sales[key] = acc.new_sales.get(key, 0.0) + sold * share
            acc.choices.append({"registration_row": "new sales", "vehicle_class": fhwa_class, "fhwa_class": fhwa_class,
                                "fuel": fuel, "count": sold, "model_year": base + j,
                                "vehicle": f"default {fhwa_class} {fuel} mix", "matched_on": "turnover",
                                "assumed": "; ".join(t for t in ("new vehicles replace the ones scrapped "
                                                                 "(stock kept at its base-year count)", assumed) if t)})


def _arrays(acc: _Cohorts, h: int, path) -> Expansion:
    base = acc.base
    new = acc.new_sales
    keys = list(acc.counts)
    classes = np.array([k[1] for k in keys], dtype=object)
    years = np.array([k[3] for k in keys], dtype=np.int64)
    counts0 = np.array([acc.counts[k] for k in keys])
    ages0 = np.maximum(base - years, 0)
    counts = _cohort_counts(list(classes), ages0, counts0, h)
    for i, k in enumerate(keys):
        if k in new:
            counts[i] += new[k] * _shifted_survival(k[1], h, k[3] - base)
    miles = np.empty_like(counts)
    for i, k in enumerate(keys):
        ages = np.maximum(np.arange(h) + base - k[3], 0)
        miles[i] = k[4] if k[4] is not None else turnover.miles_at(k[1], ages)
    cache: dict = {}
    vehicles, refs = [], []
    for i, k in enumerate(keys):
        rep_key, fhwa_class, fuel, my, own_miles = k
        rep = acc.reps[rep_key]
        spec = _spec(rep, rep_key, cache, path)
        first = int(np.argmax(counts[i] > 0)) if (counts[i] > 0).any() else 0
        suffix = f":mi{own_miles:g}" if own_miles is not None else ""
        vehicles.append(replace(spec, vehicle_id=f"{fhwa_class}:{rep_key}:{fuel}:MY{my}{suffix}",
                                vehicle_class=fhwa_class, fuel=fuel, count=float(counts[i, first]),
                                annual_miles=float(miles[i, first]), model_year=int(my)))
        refs.append(_reference_year(rep, my))
    warnings = []
    if acc.unmodelled:
        warnings.append(f"registrations: {acc.unmodelled:,.0f} vehicles have no representing vehicle (listed as "
                        f"'{NOT_MODELLED}' in registrations.csv) and add no miles or fuel, and no electric-vehicle fee "
                        "(ev_fee_usd_per_vehicle_year counts the simulated vehicles only)")
    return Expansion(vehicles=vehicles, fhwa_class=classes, model_year=years, reference_year=np.array(refs),
                     counts=counts, miles_per_vehicle=miles, base_year=base,
                     choices=pd.DataFrame(acc.choices, columns=CHOICE_COLUMNS), warnings=warnings)


def expand(fleet, scenarios) -> Expansion | None:
    """The cohorts of ``fleet.registrations``, or None when there are none."""
    rows = [(f"Registrations!row {r['_row']}", r) for r in fleet.registrations]
    if not rows:
        return None
    acc = _Cohorts(base_year(scenarios), {v.vehicle_id: v for v in fleet.vehicles})
    for label, row in rows:
        allocate(row, acc, label)
    expansion = build(acc, scenarios, fleet.path)
    ahead = [label for label, row in rows if row.get("model_year") is not None and row["model_year"] > acc.base + 1]
    if ahead:   # a model year sells from the autumn before; later ones are typos (2031 for 2013)
        expansion.warnings.append(f"registrations: {len(ahead)} row(s) give a model year after {acc.base + 1}, though "
                                  f"the counts describe {acc.base} ({', '.join(ahead[:5])}{' ...' if len(ahead) > 5 else ''});"
                                  " counted as new vehicles from the base year, with that model year's fuel economy: check the model_year")
    if all(s.first_fiscal_year is None for s in scenarios):
        expansion.warnings.append(f"registrations: no scenario gives first_fiscal_year; the counts are taken to "
                                  f"describe {acc.base} (models/turnover.toml default_base_year) for ages and turnover")
    return expansion


class FleetYears:
    """Per fleet row (the Vehicles rows, then the registration cohorts) the miles by budget
    year and the fuel factors a scenario gives them; what the budget arithmetic takes as
    ``years`` (:func:`fleetrun.budget.totals.scenario_frame`). Vehicles rows keep
    ``count x annual_miles x (1 + g)^(y - 1)`` and factor 1."""

    def __init__(self, fleet_vehicles, expansion: Expansion):
        self.fleet_vehicles = list(fleet_vehicles)
        self.expansion = expansion
        self._miles: dict[str, np.ndarray] = {}

    def year_miles(self, scenario) -> np.ndarray:
        if scenario.scenario_id not in self._miles:
            g = scenario.vmt_growth_pct_per_year / 100.0
            own = np.array([v.count * v.annual_miles for v in self.fleet_vehicles], dtype=float)
            growth = (1.0 + g) ** np.arange(scenario.budget_years)
            cohorts = self.expansion.year_miles(scenario, own_year1_miles(self.fleet_vehicles))
            self._miles[scenario.scenario_id] = np.vstack([own[:, None] * growth[None, :], cohorts])
        return self._miles[scenario.scenario_id]

    def fuel_factor(self, scenario) -> np.ndarray:
        return np.concatenate([np.ones(len(self.fleet_vehicles)), self.expansion.fuel_factor(scenario)])
