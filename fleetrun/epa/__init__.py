"""EPA Test Car List import (``fleetrun import-epa``): a fleet workbook and measured results
from the list EPA publishes each model year. See docs/epa-import.md.

- :mod:`fleetrun.epa.reader`: the CSV read and its columns mapped to fleetrun names;
- :mod:`fleetrun.epa.rules`: the derivation rules (constants in models/epa_import.toml);
- :mod:`fleetrun.epa.derive`, :mod:`~fleetrun.epa.vehicle`, :mod:`~fleetrun.epa.measured`:
  vehicles, exclusions and measured results;
- :mod:`fleetrun.epa.writer`: the workbook and the measured-results CSV.
"""
from __future__ import annotations

from fleetrun.epa.derive import ImportResult, import_rows
from fleetrun.epa.reader import read_test_car_list


def import_test_car_list(path, model_years=(), makes=()) -> ImportResult:
    """Read the list in ``path`` and derive the fleet (see :func:`fleetrun.epa.derive.import_rows`)."""
    return import_rows(read_test_car_list(path), model_years, makes)


__all__ = ["ImportResult", "import_rows", "import_test_car_list", "read_test_car_list"]
