"""Open an untrusted .xlsx file safely.

A workbook comes from whoever emailed it. Before any reader parses it we check that the path
is a regular file of bounded size (``/dev/zero`` is not), that it is a zip with the parts of an
Office Open XML workbook, that it cannot decompress into gigabytes (a zip bomb), that no XML
part declares a DTD (entity-expansion tricks such as "billion laughs" or external entities),
and (:func:`scan_sheets`) that the sheets read span a bounded number of cells: a reader that
builds a dense table allocates rows x columns of the *used range*, so one cell reference such as
``ZZZZZZZZZZ2`` or ``XFD1048576`` in an 18 KB file would ask for terabytes.
"""
from __future__ import annotations

import posixpath
import re
import zipfile
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.fileio import refuse_unreadable_size

from defusedxml.ElementTree import fromstring

MAX_FILE_BYTES = 500_000_000            # the workbook file itself (a 100,000-row fleet: ~10 MB)
MAX_TOTAL_UNCOMPRESSED = 1_000_000_000   # 1 GB: a 100,000-row fleet is ~0.1 GB of XML
EXCEL_MAX_ROWS = 1_048_576               # Excel's own sheet limits (ECMA-376; Excel specifications)
EXCEL_MAX_COLUMNS = 16_384               # XFD
# rows x columns of a sheet's used range (~45 B each read, 0.7 GB at the limit): room for a
# 400,000-row fleet of 40 columns; the 360,000-row fleet docs/benchmarks-run.md runs, with every
# Vehicles column of the interface, is 12.2 M (a limit at its own size refused it once columns
# were added)
MAX_SHEET_CELLS = 16_000_000
SPARSE_FLOOR_CELLS = 1_000_000           # a used range beyond this must be filled ...
MIN_FILL = 1 / 16                        # ... at least this much: else a stray far cell
MAX_TAG_BYTES = 64_000_000               # one XML tag or cell text
SCAN_CHUNK_BYTES = 1 << 22
MAX_MEMBERS = 10_000
MAX_RATIO = 200                          # workbook XML compresses ~5-50x; bombs 1000x+
RATIO_CHECK_MIN_BYTES = 10_000_000       # small parts may compress extremely well; harmless
DTD_SCAN_BYTES = 4096                    # a DOCTYPE must come before the root element

HINT = "Save it from Excel (or LibreOffice) as an .xlsx workbook and try again."


def is_office_lock_file(path: Path) -> bool:
    """Whether ``path`` is the owner file Excel (or Word) keeps beside an open workbook,
    ``~$fleet.xlsx``: not a workbook, and gone when the workbook is closed."""
    return Path(path).name.startswith("~$")


def _refuse_unopenable(path: Path) -> None:
    """InputError for a workbook that cannot be opened (no permission, locked by another program),
    is empty, or is an Office lock file: said as such, not as a corrupt workbook."""
    try:
        with open(path, "rb") as handle:
            handle.read(1)
    except OSError as exc:
        raise InputError(f"cannot be read ({exc.strerror or exc})", file=path,
                         hint="Check its permissions, or close the program that holds it, and try again") from None
    if is_office_lock_file(path):
        raise InputError("is the lock file Excel keeps while a workbook is open, not a workbook", file=path,
                         hint=f"Give the workbook itself ({path.name[2:]})")
    if path.stat().st_size == 0:
        raise InputError("is empty (0 bytes)", file=path,
                         hint="It was not saved completely (or is still being copied); save it again from Excel")


def check_xlsx(path: Path) -> None:
    """Raise InputError unless ``path`` looks like a safe, genuine .xlsx workbook."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path, hint="Check the path.")
    if path.is_dir():
        raise InputError("is a folder, not a workbook", file=path, hint="Give the .xlsx file.")
    if path.suffix.lower() == ".xls":
        raise InputError("old-style .xls workbooks are not supported", file=path, hint=HINT)
    refuse_unreadable_size(path, MAX_FILE_BYTES, "workbooks", "Give the path of an .xlsx workbook",
                           "Split the fleet into smaller workbooks (fleetrun run --config batch.toml runs them together)")
    if path.suffix.lower() in (".xlsm", ".xltm"):
        raise InputError("macro-enabled workbooks are refused", file=path, hint=HINT)
    _refuse_unopenable(path)
    if path.suffix.lower() in (".csv", ".txt") and not zipfile.is_zipfile(path):
        raise InputError("is a CSV file, not a fleet workbook", file=path,
                         hint=f"A registration extract becomes one with `fleetrun import-registrations {path.name} -o "
                              f"{path.stem}.xlsx`; a fleet saved as CSV: save it from Excel as an .xlsx workbook")
    if not zipfile.is_zipfile(path):
        raise InputError("is not an .xlsx workbook (not a zip file; corrupt, or another format "
                         "such as .xls or .csv renamed)", file=path, hint=HINT)
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            names = {m.filename for m in members}
            if "[Content_Types].xml" not in names or "xl/workbook.xml" not in names:
                raise InputError("is a zip file but not an .xlsx workbook (no xl/workbook.xml)",
                                 file=path, hint=HINT)
            if len(members) > MAX_MEMBERS:
                raise InputError(f"has {len(members)} parts; refusing to open it (zip bomb?)",
                                 file=path, hint=HINT)
            total = sum(m.file_size for m in members)
            if total > MAX_TOTAL_UNCOMPRESSED:
                raise InputError(f"would decompress to {total / 1e9:.1f} GB; refusing to open it "
                                 "(zip bomb?)", file=path, hint="Split the fleet into smaller workbooks.")
            for m in members:
                if m.file_size > RATIO_CHECK_MIN_BYTES and m.file_size > MAX_RATIO * max(m.compress_size, 1):
                    raise InputError(f"part {m.filename} expands {m.file_size / max(m.compress_size, 1):.0f}x; "
                                     "refusing to open it (zip bomb?)", file=path, hint=HINT)
            for m in members:
                if m.filename.endswith((".xml", ".rels", ".vml")):
                    with archive.open(m) as part:
                        head = part.read(DTD_SCAN_BYTES).upper()
                    if b"<!DOCTYPE" in head or b"<!ENTITY" in head:
                        raise InputError(f"part {m.filename} declares a DTD or XML entities; refusing "
                                         "to open it (XML entity attack?)", file=path, hint=HINT)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, NotImplementedError) as exc:
        raise InputError(f"is corrupt ({exc})", file=path, hint=HINT) from None


# --- the used range of the sheets read ------------------------------------------------------

_PREFIXED = re.compile(rb"<\w+:(?:c|row)[\s/>]")          # <x:c ...>, <x:row ...>
# The r attribute of a cell or row. Patterns start with this literal so that the regex engine
# skims the text (a leading character class made the scan 10x slower); a column reference
# needs row digits after its letters, so operator="between" and the like never match.
_REF_HEAD = rb'r="'


@lru_cache(maxsize=None)
def _letters(n: int, exact: bool = False) -> re.Pattern:
    """A cell reference whose column has ``n`` (or more, unless exact) letters."""
    return re.compile(_REF_HEAD + rb"([A-Za-z]{%d}%s)[0-9]+\"" % (n, b"" if exact else b"[A-Za-z]*"))


@lru_cache(maxsize=None)
def _digits(n: int, exact: bool = False) -> re.Pattern:
    """A reference whose row has ``n`` (or more, unless exact) digits (leading zeros aside). The
    letters and zeros are taken possessively (``*+``): what follows them is never a letter or a
    zero, so giving one back never makes a match, and the engine does not try (a 10 MB sheet:
    15 -> 10 ms a search)."""
    return re.compile(_REF_HEAD + rb"[A-Za-z]*+0*+([1-9][0-9]{%d}%s)\"" % (n - 1, b"" if exact else b"[0-9]*"))


WINDOW_BYTES = 1 << 16   # the ends of a chunk where its largest reference is looked for first


def _largest(text: bytes, exact: re.Pattern, above, order) -> bytes | None:
    """The largest (by ``order``) of ``exact``'s matches in ``text``, or None if it has none: a
    candidate from the text's two ends (a table is written in order), confirmed by one search for
    a match above it (the pattern ``above(candidate)``); only where that finds one is every match
    listed. A match in an end is a match in the text: a reference starts with ``r="`` and ends
    at its closing quote, neither of which a reference holds."""
    ends = exact.findall(text[:WINDOW_BYTES]) + exact.findall(text[-WINDOW_BYTES:])
    if ends:
        candidate = max(ends, key=order)
        if not above(candidate).search(text):
            return candidate
    found = set(exact.findall(text))
    return max(found, key=order) if found else None


def _greater(value: bytes, first: int, last: int) -> bytes:
    """A regular expression for the strings as long as ``value``, of the characters ``first``
    to ``last`` (in that order), that come after ``value``."""
    options = [re.escape(value[:i]) + b"[%c-%c]" % (ch + 1, last) + b"[%c-%c]{%d}" % (first, last, len(value) - i - 1)
               for i, ch in enumerate(value) if ch < last]
    return b"|".join(options) or b"(?!)"


@lru_cache(maxsize=64)
def _letters_above(letters: bytes) -> re.Pattern:
    """A reference whose column has as many letters as ``letters`` and comes after it (letters
    of either case; the ``r="`` before them as written, so that the search skims: a pattern
    ignoring case throughout made it 7x slower)."""
    return re.compile(_REF_HEAD + rb"(?i:%s)[0-9]+\"" % _greater(letters.upper(), ord("A"), ord("Z")))


@lru_cache(maxsize=64)
def _digits_above(digits: bytes) -> re.Pattern:
    """A reference whose row has as many digits as ``digits`` (leading zeros aside) and is larger."""
    return re.compile(_REF_HEAD + rb"[A-Za-z]*+0*+(?:%s)\"" % _greater(digits, ord("0"), ord("9")))


def _column_of(letters: bytes) -> int:
    return column_number(letters.decode("ascii"))


def _widest(text: bytes, path: Path, sheet: str) -> int:
    """The largest column index referenced in ``text`` (an upper bound of 26 when every
    reference has one letter: exact values only where they matter and are cheap)."""
    if not _letters(2).search(text):   # one pass where every reference has one letter
        return 26
    three = _letters(3).search(text) is not None   # three letters or more: AAA and beyond
    found = three and _letters(4).search(text)
    if found:
        _beyond(path, sheet, found.group(0)[3:-1].decode("ascii", "replace"), "column XFD")
    for n in ((3, 2) if three else (2,)):
        letters = _largest(text, _letters(n, exact=True), _letters_above, _column_of)
        if letters is not None:
            widest = _column_of(letters)
            if widest > EXCEL_MAX_COLUMNS:
                match = _letters(n).search(text)
                _beyond(path, sheet, match.group(0)[3:-1].decode("ascii"), "column XFD")
            return widest
    return 26


def _deepest(text: bytes, path: Path, sheet: str) -> int:
    """The largest row number referenced in ``text`` (upper bounds 99,999 / 9,999 where no
    reference has six / five digits)."""
    if not _digits(5).search(text):    # one pass where every row number has four digits or fewer
        return 9_999
    seven = _digits(7).search(text) is not None    # seven digits or more: row 1,000,000 and beyond
    found = seven and _digits(8).search(text)
    if found:
        _beyond(path, sheet, found.group(0)[3:-1].decode("ascii", "replace"), f"row {EXCEL_MAX_ROWS:,}")
    for n in ((7, 6) if seven else (6,)):
        digits = _largest(text, _digits(n, exact=True), _digits_above, int)
        if digits is not None:
            deepest = int(digits)
            if deepest > EXCEL_MAX_ROWS:
                match = _digits(n).search(text)
                _beyond(path, sheet, match.group(0)[3:-1].decode("ascii"), f"row {EXCEL_MAX_ROWS:,}")
            return deepest
    return 99_999 if _digits(5).search(text) else 9_999


def _started(text: bytes, tag: bytes, longer: bytes = b"") -> int:
    """How many ``tag`` elements start in ``text`` (unprefixed): one count where every ``tag`` is
    followed by a space (the usual writing) or by ``longer``'s next letter (``<col``, ``<cols``
    beside ``<c``: a started ``tag`` is followed by a space, ``>``, ``/`` or a line break, never
    by that letter), which one search for any other follower tells; one count per possible
    next character otherwise."""
    spaced = text.count(tag + b" ")
    if not _other_follower(tag, longer[len(tag):]).search(text):
        return spaced
    return sum(text.count(tag + end) for end in (b" ", b">", b"/", b"\n", b"\t", b"\r"))


@lru_cache(maxsize=None)
def _other_follower(tag: bytes, letter: bytes) -> re.Pattern:
    """``tag`` followed by a byte other than a space and ``letter`` (one regex search: cheaper
    than the two counts, of ``tag`` and of ``longer``, that it replaces)."""
    return re.compile(re.escape(tag) + b"[^ " + re.escape(letter) + b"]")


RARE_TRIES = 2048   # occurrences of the rare byte _holds looks at (~0.5 ms) before it searches as ``in`` does (~3 ms per 4 MB)


def _holds(text: bytes, patterns: tuple[bytes, ...], rare: int = 0) -> bool:
    """Whether ``text`` holds one of ``patterns`` (``any(p in text for p in patterns)``), found
    from the occurrences of their common byte at index ``rare`` (``:`` of a namespace prefix, ``f``
    of ``<f``), which sheet XML seldom holds: ``in`` steps almost byte by byte where a pattern
    starts or ends with a byte the text is full of (``<``, ``c``), a memchr for the rare byte does
    not. Where that byte occurs more than RARE_TRIES times, ``in`` after all."""
    byte = patterns[0][rare:rare + 1]
    at = text.find(byte, rare)
    for _ in range(RARE_TRIES):
        if at < 0:
            return False
        if text.startswith(patterns, at - rare):
            return True
        at = text.find(byte, at + 1)
    return any(p in text for p in patterns)


def _count_tags(text: bytes) -> tuple[int, int]:
    """(cells, rows) started in ``text``, counted without building match lists."""
    cells, rows = _started(text, b"<c", longer=b"<co"), _started(text, b"<row")
    if _holds(text, (b":c", b":row")):
        prefixed = _PREFIXED.findall(text)
        cells += sum(1 for tag in prefixed if b":c" in tag)
        rows += sum(1 for tag in prefixed if b":row" in tag)
    return cells, rows


@dataclass
class SheetScan:
    """What the pre-scan of one sheet found besides its extent (the reader reports neither)."""
    hidden_rows: list[int] = field(default_factory=list)
    hidden_columns: list[int] = field(default_factory=list)
    # (row, col) -> "=..." a formula without a saved result, "#N/A" (any "#...") an Excel error
    # value (the reader sees both as blank), PERCENT a number shown as a percentage
    uncached_formulas: dict[tuple[int, int], str] = field(default_factory=dict)
    percent_styles: frozenset = frozenset()      # style indices whose number format shows %


_HIDDEN_ROW = re.compile(rb'<(?:\w+:)?row\b[^>]*?\br="([0-9]+)"[^>]*?\bhidden="(?:1|true)"')
_HIDDEN_ROW_REVERSED = re.compile(rb'<(?:\w+:)?row\b[^>]*?\bhidden="(?:1|true)"[^>]*?\br="([0-9]+)"')
_HIDDEN_COL = re.compile(rb'<(?:\w+:)?col\b([^>]*?)\bhidden="(?:1|true)"([^>]*)>')
_MIN_MAX = re.compile(rb'\b(min|max)="([0-9]+)"')
# a cell whose formula has no saved value: <c r="F2"><f>1000*12</f></c> (or <v/>, <v></v>)
_UNCACHED = re.compile(rb'<(?:\w+:)?c\b[^>]*?\br="([A-Za-z]+)([0-9]+)"[^>]*>\s*'
                       rb'<(?:\w+:)?f\b[^>]*?(?:/>|>([^<]*)</(?:\w+:)?f>)\s*'
                       rb'(?:<(?:\w+:)?v\s*/>|<(?:\w+:)?v>\s*</(?:\w+:)?v>)?\s*</(?:\w+:)?c>')


PERCENT = "%"
# a cell holding an Excel error value: <c r="F2" t="e"><f>1/0</f><v>#DIV/0!</v></c>
_ERROR_CELL = re.compile(rb'<(?:\w+:)?c\b[^>]*?\br="([A-Za-z]+)([0-9]+)"[^>]*?\bt="e"[^>]*>'
                         rb'(?:(?!</(?:\w+:)?c>).)*?<(?:\w+:)?v>([^<]*)</(?:\w+:)?v>', re.S)
_ERROR_CELL_REVERSED = re.compile(rb'<(?:\w+:)?c\b[^>]*?\bt="e"[^>]*?\br="([A-Za-z]+)([0-9]+)"[^>]*>'
                                  rb'(?:(?!</(?:\w+:)?c>).)*?<(?:\w+:)?v>([^<]*)</(?:\w+:)?v>', re.S)
_STYLED_CELL = re.compile(rb'<(?:\w+:)?c\b[^>]*?\br="([A-Za-z]+)([0-9]+)"[^>]*?\bs="([0-9]+)"')
_STYLED_CELL_REVERSED = re.compile(rb'<(?:\w+:)?c\b[^>]*?\bs="([0-9]+)"[^>]*?\br="([A-Za-z]+)([0-9]+)"')


def _cell_notes(text: bytes, scan: SheetScan) -> None:
    """Excel error values and percent-formatted cells (searched only where the text mentions
    an error type or a percent style)."""
    if b't="e"' in text:
        for pattern in (_ERROR_CELL, _ERROR_CELL_REVERSED):
            for letters, row, value in pattern.findall(text):
                key = (int(row), column_number(letters.decode("ascii")))
                scan.uncached_formulas[key] = value.decode("utf-8", "replace").strip() or "#VALUE!"
    if scan.percent_styles and b' s="' in text:
        for letters, row, style in _STYLED_CELL.findall(text):
            if int(style) in scan.percent_styles:
                scan.uncached_formulas.setdefault((int(row), column_number(letters.decode("ascii"))), PERCENT)
        for style, letters, row in _STYLED_CELL_REVERSED.findall(text):
            if int(style) in scan.percent_styles:
                scan.uncached_formulas.setdefault((int(row), column_number(letters.decode("ascii"))), PERCENT)


BUILTIN_PERCENT_FORMATS = {9, 10}        # 0% and 0.00% (ECMA-376 Part 1, 18.8.30)


def percent_styles(archive: zipfile.ZipFile) -> frozenset:
    """Indices of the cell formats (styles.xml cellXfs) that show a number as a percentage."""
    member = _member(archive, "/xl/styles.xml")
    if member is None:
        return frozenset()
    root = fromstring(archive.read(member))
    custom = {int(f.get("numFmtId", -1)) for f in root.iter() if _local(f.tag) == "numFmt"
              and "%" in (f.get("formatCode") or "").replace('"%"', "").replace("\\%", "")}
    found = set()
    for holder in root.iter():
        if _local(holder.tag) == "cellXfs":
            for index, xf in enumerate(x for x in holder if _local(x.tag) == "xf"):
                number_format = int(xf.get("numFmtId", 0) or 0)
                if number_format in BUILTIN_PERCENT_FORMATS or number_format in custom:
                    found.add(index)
    return frozenset(found)


def _notes(text: bytes, scan: SheetScan) -> None:
    """Hidden rows and columns, formulas without a saved result (searched only where the
    text mentions them: most sheets have none)."""
    if b'hidden="' in text:
        for pattern in (_HIDDEN_ROW, _HIDDEN_ROW_REVERSED):
            scan.hidden_rows.extend(int(r) for r in pattern.findall(text))
        for before, after in _HIDDEN_COL.findall(text):
            bounds = dict(_MIN_MAX.findall(before + after))
            first, last = int(bounds.get(b"min", 0)), int(bounds.get(b"max", 0))
            scan.hidden_columns.extend(range(first, min(last, first + 1000) + 1))
    if _holds(text, (b"<f",), rare=1) or _holds(text, (b":f",)):
        for letters, row, formula in _UNCACHED.findall(text):
            key = (int(row), column_number(letters.decode("ascii")))
            body = formula.decode("utf-8", "replace")
            scan.uncached_formulas[key] = "=" + body if body else "=(shared formula)"


def column_number(letters: str) -> int:
    """A column's letters as its 1-based index (A = 1, XFD = 16,384)."""
    index = 0
    for ch in letters.upper():
        index = index * 26 + (ord(ch) - 64)
    return index


def _local(tag: str) -> str:
    """An XML name without its namespace: transitional and Strict OOXML (ISO 29500 Strict,
    ``http://purl.oclc.org/ooxml/...``) name the same elements in different namespaces."""
    return tag.rsplit("}", 1)[-1]


def _member(archive: zipfile.ZipFile, target: str) -> str | None:
    """The zip member a relationship target names, found as a reader finds it: absolute
    (``/xl/...``) or relative to ``xl/``, backslashes as slashes, letter case ignored."""
    target = target.replace("\\", "/")
    path = target.lstrip("/") if target.startswith("/") else "xl/" + target
    path = posixpath.normpath(path).lstrip("/").casefold()
    for name in archive.namelist():
        if name.replace("\\", "/").casefold() == path:
            return name
    return None


def sheet_parts(archive: zipfile.ZipFile) -> dict[str, str | None]:
    """Sheet name -> worksheet part (None where no part can be found), from xl/workbook.xml and
    its relationships (defusedxml), namespaces and letter case as a reader takes them."""
    book = fromstring(archive.read(_member(archive, "/xl/workbook.xml") or "xl/workbook.xml"))
    targets = {}
    rels = _member(archive, "/xl/_rels/workbook.xml.rels")
    if rels:
        for rel in fromstring(archive.read(rels)).iter():
            if _local(rel.tag) == "Relationship":
                targets[rel.get("Id")] = _member(archive, rel.get("Target", ""))
    parts = {}
    for sheet in book.iter():
        if _local(sheet.tag) != "sheet":
            continue
        rel_id = next((v for k, v in sheet.attrib.items() if _local(k) == "id"), None)
        parts[sheet.get("name", "")] = targets.get(rel_id)
    return parts


def _worksheet_members(archive: zipfile.ZipFile) -> list[str]:
    return [n for n in archive.namelist() if n.casefold().startswith("xl/worksheets/")
            and n.casefold().endswith(".xml")]


def scan_sheets(path: Path, names) -> dict[str, SheetScan]:
    """InputError unless each named sheet's cell references lie within Excel's limits and its
    used range spans at most MAX_SHEET_CELLS cells; what else the scan found, by sheet name.
    Sheets are matched by name without letter case; where a sheet's part cannot be told, every
    worksheet part is scanned (fail closed). Streams the sheet XML in chunks."""
    scans: dict[str, SheetScan] = {}
    wanted = {str(n).casefold() for n in names}
    try:
        with zipfile.ZipFile(path) as archive:
            parts = sheet_parts(archive)
            styles = percent_styles(archive)
            for name, part in parts.items():
                if name.casefold() in wanted and part:
                    scans[name] = _scan_part(archive, part, name, path, styles)
            if any(part is None for part in parts.values()) or not parts:
                for part in _worksheet_members(archive):
                    if part not in parts.values():
                        _scan_part(archive, part, part, path)
    except (zipfile.BadZipFile, OSError, EOFError, KeyError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"is corrupt ({type(exc).__name__}: {exc})", file=path, hint=HINT) from None
    return scans


def _scan_part(archive: zipfile.ZipFile, part: str, sheet: str, path: Path,
               styles: frozenset = frozenset()) -> SheetScan:
    max_row = max_col = rows = unreferenced = total_cells = 0
    scan = SheetScan(percent_styles=styles)
    for text in _whole_tags(archive, part, sheet, path):
        max_col = max(max_col, _widest(text, path, sheet))
        max_row = max(max_row, _deepest(text, path, sheet))
        cells, found_rows = _count_tags(text)
        rows += found_rows
        total_cells += cells
        unreferenced += max(0, cells - text.count(b' r="') - (text.count(b'\nr="') if b"\n" in text else 0))
        _notes(text, scan)
        _cell_notes(text, scan)
    # cells without a reference take the next column: bound their reach by their number
    width = max(max_col, unreferenced)
    height = max(max_row, rows)
    if SPARSE_FLOOR_CELLS < width * height <= MAX_SHEET_CELLS and total_cells < MIN_FILL * width * height:
        # width and height are upper bounds (cheap to find): measure the reach before refusing,
        # or a 10,000-row table would count as 99,999 rows deep and as mostly empty
        row, column, reference = _farthest_cell(archive, part, sheet, path)
        reach = max(row, rows) * max(column, unreferenced)
        if reach > SPARSE_FLOOR_CELLS and total_cells < MIN_FILL * reach:
            raise InputError(f"{sheet}!{reference or '?'}: a cell far from the table, which the "
                             f"sheet's {total_cells:,} cells do not fill", file=path,
                             hint="Delete the stray cells far from the table (Ctrl+End in Excel shows the last one)")
    if width * height > MAX_SHEET_CELLS:
        raise InputError(f"sheet {sheet} spans {height:,} rows x {width:,} columns (its last row {max_row:,}, "
                         f"its last column {max_col:,}); fleetrun reads at most {MAX_SHEET_CELLS:,} cells per sheet",
                         file=path,
                         hint="Delete stray cells far from the table, or split the fleet into smaller "
                              "workbooks (fleetrun run --config batch.toml runs them together)")
    return scan


_REFERENCE = re.compile(rb'<(?:\w+:)?c\b[^>]*?\br="([A-Za-z]{1,3})([0-9]{1,7})"')


def _whole_tags(archive: zipfile.ZipFile, part: str, sheet: str, path: Path):
    """A sheet part's bytes in chunks of about SCAN_CHUNK_BYTES, each cut after a ``>`` so no
    tag is split; InputError for a tag or text longer than MAX_TAG_BYTES."""
    carry = b""
    with archive.open(part) as stream:
        while True:
            block = stream.read(SCAN_CHUNK_BYTES)
            data = carry + block
            cut = len(data) if not block else data.rfind(b">") + 1
            text, carry = data[:cut], data[cut:]
            if len(carry) > MAX_TAG_BYTES:
                raise InputError(f"sheet {sheet} has a tag or text longer than {MAX_TAG_BYTES / 1e6:.0f} MB; "
                                 "refusing to read it", file=path, hint=HINT)
            yield text
            if not block:
                return


def _farthest_cell(archive: zipfile.ZipFile, part: str, sheet: str, path: Path) -> tuple[int, int, str]:
    """(row, column, reference) of the cell farthest down (then right) in a sheet part: a
    second pass, only where the first pass's bounds suggest a problem."""
    best = (0, 0, "")
    for text in _whole_tags(archive, part, sheet, path):
        for letters, digits in _REFERENCE.findall(text):
            key = (int(digits), column_number(letters.decode("ascii")))
            if key > best[:2]:
                best = (*key, (letters + digits).decode("ascii"))
    return best


def _beyond(path: Path, sheet: str, ref: str, limit: str) -> None:
    shown = ref if len(ref) <= 20 else ref[:17] + "..."
    raise InputError(f"{sheet}!{shown}: the cell reference lies beyond Excel's last {limit}; the file "
                     "is damaged or was not written by a spreadsheet program", file=path, hint=HINT)
