"""The fleet: workbook I/O and validation, the batch runner, and its reports."""
from fleetrun.fleet.workbook import Fleet, Scenario, read_fleet

__all__ = ["Fleet", "Scenario", "read_fleet"]
