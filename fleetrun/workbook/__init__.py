"""Workbook input: the fleet workbook's schema, cell parsing, the safe reader and the template.

Below both the fleet run and the diagnosis: a value typed in a workbook, a vehicle TOML or a
diagnose sidecar is parsed by the same rules (:mod:`fleetrun.workbook.rows`).
"""
from fleetrun.workbook.reader import Fleet, Scenario, read_fleet

__all__ = ["Fleet", "Scenario", "read_fleet"]
