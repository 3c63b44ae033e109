"""Turning one workbook cell into a typed value, or a one-line reason why not.

Each parser returns the value or raises :class:`CellProblem` whose text completes a message
like ``Vehicles!H4 peak_engine_torque_Nm: 'abc' is not a number``.
"""
from __future__ import annotations

import datetime as _dt
import difflib
import math
import re
import unicodedata

from fleetrun.errors import InputError
from fleetrun.simulation.tyre import tire_diameter_m


class CellProblem(ValueError):
    """The cell's value cannot be used; ``str()`` says why, quoting the value."""


def show(value) -> str:
    """A cell value as the message quotes it: ``'abc'``, ``-3``, ``2024-01-05``."""
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return repr(text)
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    if isinstance(value, (_dt.datetime, _dt.date)):
        return value.isoformat()
    return repr(value) if isinstance(value, str) else str(value)


def is_blank(value) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


# Characters a cell shows as nothing: zero-width space/joiners, word joiner, BOM, soft hyphen,
# Mongolian vowel separator, bidirectional marks; and control characters but tab and newlines.
_INVISIBLE = re.compile("[\u200b-\u200f\u2060-\u2064\u202a-\u202e\u2066-\u2069\ufeff\u00ad\u180e"
                        "\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f]")
# Letters of other scripts that look like Latin ones (Unicode TR 39 confusables, the common ones)
_LOOKALIKES = str.maketrans(dict(zip(
    "\u0430\u0435\u043e\u0440\u0441\u0443\u0445\u0456\u0458\u0455\u0501\u04cf"
    "\u0410\u0412\u0415\u041a\u041c\u041d\u041e\u0420\u0421\u0422\u0425\u0423\u0406\u0408\u0405"
    "\u03bf\u03bd\u0391\u0392\u0395\u0396\u0397\u0399\u039a\u039c\u039d\u039f\u03a1\u03a4\u03a5\u03a7",
    "aeopcyxijsdl" "ABEKMHOPCTXYIJS" "ovABEZHIKMNOPTYX")))


def skeleton(text: str) -> str:
    """``text`` as it looks: compatibility forms folded (NFKC) and look-alike letters of other
    scripts replaced by the Latin letters they imitate."""
    return unicodedata.normalize("NFKC", text).translate(_LOOKALIKES)


def lookalike_letters(text: str) -> list[str]:
    """The letters of ``text`` that only look Latin, described (``'і' (CYRILLIC SMALL ...)``)."""
    if text.isascii():   # every id of most fleets: no letter of another script (each is looked at below)
        return []
    return [f"{ch!r} ({unicodedata.name(ch, 'U+%04X' % ord(ch))}, U+{ord(ch):04X})" for ch in dict.fromkeys(text)
            if ord(ch) > 127 and ch.translate(_LOOKALIKES) != ch]


def _check_visible(text: str, value) -> None:
    found = _INVISIBLE.search(text)
    if found:
        ch = found.group()
        name = unicodedata.name(ch, "a control character")
        raise CellProblem(f"{show(value)} holds an invisible character ({name}, U+{ord(ch):04X}) at "
                          f"position {found.start() + 1}; retype the cell")


def parse_id(value) -> str:
    """An id: text without invisible characters that does not mix Latin letters with
    look-alikes of other scripts (``CAR-1`` and ``САR-1`` would be two vehicles)."""
    text = parse_text(value)
    odd = lookalike_letters(text)
    if odd and any("a" <= ch.lower() <= "z" for ch in text):
        raise CellProblem(f"{show(value)} mixes Latin letters with look-alike letters of another script: "
                          f"{', '.join(odd)}; retype the id in one script")
    return text


def parse_text(value) -> str:
    if isinstance(value, bool):
        raise CellProblem(f"{show(value)} is not text")
    if isinstance(value, float) and value.is_integer():
        return str(int(value))  # an id typed as 101 arrives as 101.0 from some writers
    if isinstance(value, (_dt.datetime, _dt.date, _dt.time)):
        raise CellProblem(f"{show(value)} is a date, not text (format the column as Text)")
    text = str(value).strip()
    _check_visible(text, value)
    return text


def parse_number(value) -> float:
    if isinstance(value, bool):
        raise CellProblem(f"{show(value)} is not a number")
    if isinstance(value, (_dt.datetime, _dt.date, _dt.time)):
        raise CellProblem(f"{show(value)} is a date, not a number (format the column as Number)")
    if isinstance(value, (int, float)):
        number = float(value)
    else:
        text = str(value).strip()
        if _THOUSANDS.fullmatch(text):   # 2,524,145 typed as text (a pasted FHWA table): the number shown
            text = text.replace(",", "")
        try:
            number = float(text)
        except ValueError:
            raise CellProblem(f"{show(value)} is not a number; {_number_hint(text)}") from None
    if not math.isfinite(number):
        raise CellProblem(f"{show(value)} is not a finite number")
    return number


# Thousands separators as US / UK Excel shows them (2,524,145 or 1,234.5): unambiguous, a
# decimal comma has no three-digit groups after a non-zero lead (0,115 and 4,2 do not match)
_THOUSANDS = re.compile(r"[+-]?[1-9]\d{0,2}(,\d{3})+(\.\d+)?")
THOUSANDS_PATTERN = _THOUSANDS.pattern   # the same rule for a CSV column (registrations.extract)
_ONE_GROUP = re.compile(r"[+-]?[1-9]\d{0,2},\d{3}")   # 1,500: 1500, or 1.5 written with a decimal comma


def decimal_comma_reading(text: str) -> float | None:
    """The other reading of a text cell that :func:`parse_number` takes as thousands
    (``1,500`` as 1500): the number with its comma as a decimal comma (1.5), when that reading
    exists (one three-digit group and no decimal point; ``1,234,567`` and ``1,234.5`` have none)."""
    text = str(text).strip()
    return float(text.replace(",", ".")) if _ONE_GROUP.fullmatch(text) else None


_GROUPED = re.compile(r"[+-]?\d{1,3}([ .'\u00a0\u202f]\d{3})+(,\d+)?")   # 2 524 145, 2.524.145, 2'524'145
_MONTHS = ("january", "february", "march", "april", "may", "june", "july", "august", "september",
           "october", "november", "december")


def _number_hint(text: str) -> str:
    """What to type instead of ``text``, a cell that is not a number."""
    lower = text.lower().rstrip(".")
    months = [k for k, name in enumerate(_MONTHS, start=1) if len(lower) >= 3 and name.startswith(lower[:3])
              and (name.startswith(lower) or lower in ("sept",))]
    if months:
        return f"give the month as a number 1-12 ({_MONTHS[months[0] - 1].capitalize()} = {months[0]})"
    if text.startswith("#"):   # #DIV/0!, #N/A, #REF! as text
        return "an Excel error; fix the formula or type the value"
    if re.match(r"[+-]?[$€£]", text):   # $0.20, -$5 (a one-letter text's empty slice is in every string)
        return "type the number without the currency sign"
    if text.endswith("%"):
        return "type the number without the % sign (1.5 for 1.5 %), or format the cell as Percentage"
    if _GROUPED.fullmatch(text):
        return f"type it without thousands separators ({re.sub(r'[^0-9,+-]', '', text).replace(',', '.')})"
    if re.fullmatch(r"[+-]?\d+,\d+", text):
        return f"write the decimal point as a point ({text.replace(',', '.')})"
    if re.search(r"\d", text):
        return "type the number alone, without units, labels or separators"
    return "type a number"


def parse_integer(value) -> int:
    number = parse_number(value)
    if not number.is_integer():
        raise CellProblem(f"{show(value)} is not a whole number")
    return int(number)


def parse_choice(value, choices) -> str:
    if isinstance(value, bool) and {"yes", "no"} <= set(choices):   # TRUE / FALSE typed in Excel
        return "yes" if value else "no"
    text = parse_text(value)
    lower = {c.lower(): c for c in choices}
    key = as_name(text)   # light-truck, Light Truck: light_truck
    for candidate in (text.lower(), key):
        if candidate in lower:
            return lower[candidate]
    if skeleton(key) in lower:
        raise CellProblem(f"{show(value)} looks like {lower[skeleton(key)]} but has look-alike letters of "
                          f"another script: {', '.join(lookalike_letters(text))}; retype it")
    if is_total_label(key):
        raise CellProblem(f"{show(value)} {TOTAL_ROW}")
    raise CellProblem(f"{show(value)} is not one of {', '.join(choices)}")


NAME_SPACING = r"[\s-]+"   # spaces and hyphens in a typed name: Light Truck, light-truck are light_truck


def as_name(text) -> str:
    """A header or choice as fleetrun spells its names: lower case, spaces and hyphens as ``_``."""
    return re.sub(NAME_SPACING, "_", str(text).strip().lower())


_TOTAL_WORDS = {"total", "totals", "grand_total", "sum", "all", "all_vehicles", "total_vehicles"}
TOTAL_ROW = ("looks like a total row; delete the row (fleetrun adds the rows up itself, so a total row "
             "would count them twice)")


def is_total_label(text: str) -> bool:
    """Whether a class cell reads like the label of a total row (``Total``, ``Grand total``)."""
    return as_name(str(text).strip(" :")) in _TOTAL_WORDS


def parse_onroad(value):
    """``epa_label``, ``none`` or a positive factor (on-road fuel = factor x cycle fuel)."""
    if isinstance(value, str):
        text = value.strip().lower().replace("-", "_")
        if text in ("epa_label", "none"):
            return text
    try:
        factor = parse_number(value)
    except CellProblem:
        raise CellProblem(f"{show(value)} is not epa_label, none or a factor such as 1.2") from None
    if factor <= 0:
        raise CellProblem(f"{show(value)} must be a factor greater than 0 (or epa_label, none)")
    return factor


def parse_schedule(value):
    """A number, or ``YEAR:value`` pairs (``2027:3.40, 2028:3.55``) -> {year: value}."""
    if not isinstance(value, str) or ":" not in value:
        try:
            return parse_number(value)
        except CellProblem:
            raise CellProblem(f"{show(value)} is not a number or a YEAR:value list such as 2027:3.40, 2028:3.55") from None
    schedule = {}
    for part in re.split(r"[,;]\s*", value.strip()):
        if not part.strip():
            continue
        year, _, number = part.partition(":")
        try:
            key = int(year.strip())
        except ValueError:
            raise CellProblem(f"{show(value)}: {show(part)} is not YEAR:value (e.g. 2027:3.40)") from None
        if key in schedule:
            raise CellProblem(f"{show(value)} gives fiscal year {key} twice")
        schedule[key] = parse_number(number.strip())
    if not schedule:
        raise CellProblem(f"{show(value)} is not a number or YEAR:value list")
    return schedule


_RATIO_SPLIT = re.compile(r"[,;\s]+")


def parse_ratios(value) -> tuple[float, ...]:
    """A comma list of gear ratios, first gear first (one ratio may arrive as a number)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        parts = [value]
    else:
        text = parse_text(value)
        if ";" in text and re.search(r"[0-9],[0-9]", text):
            raise CellProblem(f"{show(value)} separates with ';' and has commas inside numbers: decimal "
                              "commas? write the ratios with decimal points, separated by commas "
                              "(4.2,2.5,1.6,1.2)")
        parts = [p for p in _RATIO_SPLIT.split(text) if p]
    if not parts:
        raise CellProblem(f"{show(value)} has no gear ratios")
    ratios = []
    for part in parts:
        try:
            ratio = parse_number(part)
        except CellProblem:
            raise CellProblem(f"{show(value)} is not a comma list of numbers "
                              f"({show(part)} is not a number)") from None
        if ratio <= 0:
            raise CellProblem(f"{show(value)} has a gear ratio {show(ratio)} that is not positive")
        ratios.append(ratio)
    return tuple(ratios)


def _named_items(value, example: str, what: str):
    """The (name, number text) of each ``name:number`` item of a comma- or semicolon-separated
    list cell; a problem naming ``example`` for an item without its ``:what``."""
    for item in (p.strip() for p in re.split(r"[,;]", parse_text(value))):
        if not item:
            continue
        name, sep, number = item.rpartition(":")
        name = name.strip()
        if not sep or not name:
            raise CellProblem(f"{show(value)} is not a list like {example} ({show(item)} has no ':{what}')")
        yield name, number


def parse_cycle_mix(value) -> dict[str, float]:
    """``UDDS:0.55,HWFET:0.45`` -> {"UDDS": 0.55, "HWFET": 0.45} (order kept)."""
    mix: dict[str, float] = {}
    for name, share_text in _named_items(value, "UDDS:0.55,HWFET:0.45", "share"):
        try:
            share = parse_number(share_text)
        except CellProblem:
            raise CellProblem(f"{show(value)}: share {show(share_text.strip())} of {name} "
                              "is not a number") from None
        if share < 0:
            raise CellProblem(f"{show(value)}: share of {name} is negative")
        if name.upper() in (k.upper() for k in mix):
            raise CellProblem(f"{show(value)} names {name} twice")
        mix[name] = share
    if not mix:
        raise CellProblem(f"{show(value)} names no drive cycle")
    return mix


def parse_class_shares(value, classes) -> dict[str, float]:
    """``combination_truck:9.1, single_unit_truck:4.6`` -> {class: percent} (docs/registrations.md,
    "Miles by class"): each named class's percent of the base year's vehicle-miles; the names
    must be of ``classes`` and the percents add up to at most 100."""
    shares: dict[str, float] = {}
    for name, number in _named_items(value, "combination_truck:9.1, single_unit_truck:4.6", "percent"):
        name = name.lower()
        if name not in classes:
            near = difflib.get_close_matches(name, list(classes), n=1, cutoff=0.4)
            guess = f" (did you mean {near[0]}?)" if near else ""
            raise CellProblem(f"{show(value)}: {show(name)} is not an FHWA class{guess}; valid: {', '.join(classes)}")
        if name in shares:
            raise CellProblem(f"{show(value)} names {name} twice")
        shares[name] = parse_number(number.strip().rstrip("%").strip())   # "9.1%" is 9.1 percent
        if shares[name] < 0:
            raise CellProblem(f"{show(value)}: the percent of {name} is negative")
    if not shares:
        raise CellProblem(f"{show(value)} names no class")
    if sum(shares.values()) > 100.0 + 1e-9:
        raise CellProblem(f"{show(value)} adds up to {sum(shares.values()):g} %; at most 100")
    return shares


def parse_tire_size(value) -> str:

    text = parse_text(value)
    try:
        tire_diameter_m(text)
        return text
    except InputError:
        pass
    raise CellProblem(f"{show(value)} is not a tire size like P235/75R15, 295/75R22.5 or 11R22.5")
