"""Open an untrusted .xlsx file safely.

A workbook comes from whoever emailed it. Before openpyxl parses anything we check that the
file is a zip with the parts of an Office Open XML workbook, that it cannot decompress into
gigabytes (a zip bomb), and that no XML part declares a DTD (entity-expansion tricks such as
"billion laughs" or external entities). openpyxl then parses with defusedxml as a second line
of defence.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

from fleetrun.errors import InputError

MAX_TOTAL_UNCOMPRESSED = 1_000_000_000   # 1 GB: a 100,000-row fleet is ~0.1 GB of XML
MAX_MEMBERS = 10_000
MAX_RATIO = 200                          # workbook XML compresses ~5-50x; bombs 1000x+
RATIO_CHECK_MIN_BYTES = 10_000_000       # small parts may compress extremely well; harmless
DTD_SCAN_BYTES = 4096                    # a DOCTYPE must come before the root element

HINT = "Save it from Excel (or LibreOffice) as an .xlsx workbook and try again."


def check_xlsx(path: Path) -> None:
    """Raise InputError unless ``path`` looks like a safe, genuine .xlsx workbook."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path, hint="Check the path.")
    if path.is_dir():
        raise InputError("is a folder, not a workbook", file=path, hint="Give the .xlsx file.")
    if path.suffix.lower() == ".xls":
        raise InputError("old-style .xls workbooks are not supported", file=path, hint=HINT)
    if path.suffix.lower() in (".xlsm", ".xltm"):
        raise InputError("macro-enabled workbooks are refused", file=path, hint=HINT)
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
