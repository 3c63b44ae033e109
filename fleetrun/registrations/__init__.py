"""A fleet from registrations (docs/registrations.md): the Registrations sheet and DMV-style
extracts read, a representing vehicle chosen for every row from the shipped library, and fleet
turnover (survival, miles by age, new model years) over the budget years.

- :mod:`fleetrun.registrations.library`: the vehicle library and the matching rules;
- :mod:`fleetrun.registrations.turnover`: survival, miles by age, age distribution, trend;
- :mod:`fleetrun.registrations.expand`: rows -> cohorts with counts and miles per year;
- :mod:`fleetrun.registrations.extract`: DMV-style CSV extracts, read in chunks.
"""
from __future__ import annotations

from fleetrun.registrations.expand import CHOICE_COLUMNS, Expansion, expand

__all__ = ["CHOICE_COLUMNS", "Expansion", "expand"]
