"""A fleet workbook holding a Registrations sheet (``fleetrun import-registrations``)."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from fleetrun.workbook.schema import REGISTRATION_COLUMNS, REGISTRATIONS_SHEET, SCENARIO_COLUMNS, SCENARIOS_SHEET

# Rates are placeholders the analyst replaces (the federal ones are the 1993 federal rates).
DEFAULT_SCENARIO = {"scenario_id": "baseline", "description": "From a registration extract", "ambient_temp_C": 20,
                    "cycle_mix": "default", "budget_years": 2, "vmt_growth_pct_per_year": 1.0,
                    "state_tax_gasoline_usd_per_gal": 0.20, "state_tax_diesel_usd_per_gal": 0.20,
                    "federal_tax_gasoline_usd_per_gal": 0.184, "federal_tax_diesel_usd_per_gal": 0.244}


def write_registrations_workbook(frame: pd.DataFrame, path, first_fiscal_year=None,
                                 base_year_vmt_million=None, base_year_vmt_share_pct=None) -> Path:
    """Write ``frame`` (extract.read_extract) as the Registrations sheet and one scenario."""
    import xlsxwriter

    from fleetrun.fileio import atomic_file
    from fleetrun.workbook.text_cells import looks_like_formula

    names = [c.name for c in REGISTRATION_COLUMNS if c.name in frame.columns]
    scenario = dict(DEFAULT_SCENARIO, first_fiscal_year=first_fiscal_year,
                    base_year_vmt_million=base_year_vmt_million, base_year_vmt_share_pct=base_year_vmt_share_pct)
    scenario_names = [c.name for c in SCENARIO_COLUMNS if scenario.get(c.name) is not None]
    path = Path(path)
    with atomic_file(path) as tmp:
        book = xlsxwriter.Workbook(str(tmp), {"constant_memory": True})
        quoted = book.add_format({"quote_prefix": True})   # text that looks like a formula stays text
        sheet = book.add_worksheet(REGISTRATIONS_SHEET)
        sheet.write_row(0, 0, names)
        for r, row in enumerate(frame[names].itertuples(index=False), start=1):
            for c, value in enumerate(row):
                if value is None or (isinstance(value, float) and value != value):
                    continue
                if isinstance(value, str):
                    sheet.write_string(r, c, value, quoted if looks_like_formula(value) else None)
                else:
                    sheet.write_number(r, c, float(value))
        scenarios = book.add_worksheet(SCENARIOS_SHEET)
        scenarios.write_row(0, 0, scenario_names)
        scenarios.write_row(1, 0, [scenario[n] for n in scenario_names])
        book.close()
    return path
